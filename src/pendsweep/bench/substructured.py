"""Substructured benchmark: one point of 120 periods against the emulated point."""

from __future__ import annotations

from ..backends import make_backend
from ..model.params import FIG9_PO
from .registry import benchmark, best_of

#: Issue 3's budget: a substructured point may cost this many emulated points.
TARGET_RATIO = 15.0


@benchmark("substructured")
def bench_substructured(quick: bool) -> dict:
    """Wall time of the Fig. 9 PO point (100 + 20 periods), substructured vs emulated.

    The substructured loop runs the controller at 1 ms and the rig at 0.1 ms
    (10 RK4 substeps), with noise, the servo and first-order prediction (the
    defaults); the emulated point is the RK4 of Eq. (11) at 1 ms.
    """
    p = FIG9_PO
    periods = 20 if quick else 120
    transient, record = periods - 20 if periods > 20 else 0, min(20, periods)
    sub = make_backend("substructured", dt=1e-3, physics_substeps=10)
    emu = make_backend("emulated", dt=1e-3)
    s_sub = sub.initial_state(p, 0, 0, 0.1, 0)
    s_emu = emu.initial_state(p, 0, 0, 0.1, 0)
    sub.run_point(p, s_sub, 1, 1)  # compile / load the caches
    emu.run_point(p, s_emu, 1, 1)
    repeat = 3 if quick else 7
    t_sub = best_of(lambda: sub.run_point(p, s_sub, transient, record), repeat)
    t_emu = best_of(lambda: emu.run_point(p, s_emu, transient, record), repeat)
    ticks = periods * sub.steps_per_period(p)
    return {
        "periods": periods,
        "controller_steps": ticks,
        "physics_substeps_per_step": sub.physics_substeps,
        "substructured_point_seconds": t_sub,
        "emulated_point_seconds": t_emu,
        "ratio_substructured_over_emulated": t_sub / t_emu,
        "target_ratio_at_most": TARGET_RATIO,
        "ns_per_controller_step": 1e9 * t_sub / ticks,
    }
