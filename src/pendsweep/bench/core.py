"""Core benchmarks: the scalar RK4 kernel and the Fig. 11(a) sweep against solve_ivp."""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from scipy.integrate import solve_ivp

from ..backends import make_backend
from ..kernels import PHYSICS, eq11_params
from ..model.params import FIG9_PO, ModelParams
from ..studies.sweep import run_sweep
from ..studies.sweepfile import SWEEPS_DIR, load_sweep
from .registry import benchmark, best_of


class _Stalled(Exception):
    """solve_ivp exceeded its wall-time budget."""


def solve_ivp_point(p: ModelParams, state0, periods: int, budget_s: float = math.inf) -> np.ndarray:
    """The same point with scipy's RK45 at rtol 1e-8 (signum per evaluation).

    Raises :class:`_Stalled` after ``budget_s`` seconds: once Coulomb friction
    makes the pendulum stick, the adaptive step collapses on the sgn
    discontinuity and the integration effectively stops advancing.
    """
    q = eq11_params(p.kernel_array(), True, False)  # signum at every evaluation
    w = p.omega_e
    deadline = time.perf_counter() + budget_s

    def rhs(t, z):
        if time.perf_counter() > deadline:
            raise _Stalled
        return PHYSICS.eq11_rhs(tuple(z), (p.alpha * math.sin(w * t), 0.0), q)

    sol = solve_ivp(rhs, (0.0, periods / p.fe), state0, method="RK45", rtol=1e-8, atol=1e-10)
    return sol.y[:, -1]


def _time_solve_ivp(config, sample, periods: int, budget_s: float) -> tuple[float, int]:
    """Seconds per point over the points that finished, and how many stalled."""
    total, finished = 0.0, 0
    for v in sample:
        t0 = time.perf_counter()
        try:
            solve_ivp_point(config.params_at(v), list(config.initial), periods, budget_s)
        except _Stalled:
            continue
        total += time.perf_counter() - t0
        finished += 1
    return (total / finished if finished else math.nan), len(sample) - finished


@benchmark("core")
def bench_core(quick: bool) -> dict:
    """ns per RK4 step, the Fig. 11(a) sweep, and solve_ivp on the same points."""
    backend = make_backend("emulated")
    state = backend.initial_state(FIG9_PO, 0, 0, 0.1, 0)
    periods = 20 if quick else 120
    backend.run_point(FIG9_PO, state, 1, 1)  # compile / load the cache
    steps = periods * backend.steps_per_period(FIG9_PO)
    t_point = best_of(lambda: backend.run_point(FIG9_PO, state, periods - 20 if periods > 20 else 0, 20), 5)

    spec = load_sweep(SWEEPS_DIR / "fig11a.toml")
    config = spec.config
    if quick:
        config = replace(config, values=config.values[::10], transient_periods=10, record_periods=10)
    n_points = len(config.values)
    per_point = config.transient_periods + config.record_periods
    t_sweep = best_of(lambda: run_sweep(config, None, n_jobs=1), 1 if quick else 3)

    def integrate_only(cfg):
        """The sweep's integration alone: state carried, no classification."""
        state = backend.initial_state(cfg.params_at(cfg.values[0]), *cfg.initial)
        for v in cfg.values:
            state = backend.run_point(cfg.params_at(v), state, cfg.transient_periods, cfg.record_periods).state

    t_integrate = best_of(lambda: integrate_only(config), 1 if quick else 3)
    smooth = replace(config, model=dict(config.model, b1=0.0, b3=0.0))
    t_integrate_smooth = best_of(lambda: integrate_only(smooth), 1 if quick else 3)

    # solve_ivp is timed on a sample of the same points (fresh starts) and scaled to the sweep.
    sample = config.values[:: max(1, n_points // (3 if quick else 6))]
    budget = 2.0 if quick else 20.0
    ivp_paper, stalled = _time_solve_ivp(config, sample, per_point, budget)
    ivp_smooth, stalled_smooth = _time_solve_ivp(smooth, sample, per_point, budget)
    return {
        "ns_per_rk4_step_single_point": 1e9 * t_point / steps,
        "fig11a_points": n_points,
        "fig11a_periods_per_point": per_point,
        "fig11a_integration_seconds_one_core": t_integrate,
        "fig11a_sweep_seconds_one_core_with_classification": t_sweep,
        "fig11a_target_seconds": 2.0,
        "fig11a_smooth_damping_integration_seconds": t_integrate_smooth,
        "solve_ivp_sample_points": len(sample),
        "solve_ivp_budget_seconds_per_point": budget,
        "solve_ivp_paper_damping_points_stalled": stalled,
        "solve_ivp_paper_damping_seconds_per_finished_point": ivp_paper,
        "solve_ivp_smooth_damping_points_stalled": stalled_smooth,
        "solve_ivp_smooth_damping_sweep_seconds_estimated": ivp_smooth * n_points,
        "speedup_vs_solve_ivp_smooth_damping": ivp_smooth * n_points / t_integrate_smooth,
        "speedup_vs_solve_ivp_paper_damping_lower_bound": (
            budget * n_points / t_integrate if stalled else ivp_paper * n_points / t_integrate
        ),
        "note": "RK45 stalls on the Coulomb sgn discontinuity once the pendulum sticks; "
        "stalled points are cut at the budget, so the paper-damping ratio is a lower bound",
    }
