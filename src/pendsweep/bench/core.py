"""Core benchmarks: the scalar RK4 kernel and the Fig. 11(a) sweep against solve_ivp."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from ..backends import make_backend
from ..params import FIG9_PO, ModelParams
from ..sweep import run_sweep
from ..sweepfile import load_sweep
from . import benchmark, best_of

SWEEPS = Path(__file__).resolve().parents[3] / "sweeps"


def solve_ivp_point(p: ModelParams, state0, periods: int) -> np.ndarray:
    """The same point with scipy's RK45 at rtol 1e-8 (signum per evaluation)."""
    m, l, b1, b2, b3, g, M, C, K, k3 = p.kernel_array()
    w = p.omega_e

    def rhs(t, z):
        y, yd, th, thd = z
        s, c = math.sin(th), math.cos(th)
        sg = math.copysign(1.0, thd) if thd != 0 else 0.0
        fd = b1 * sg + b2 * thd + b3 * thd * thd * sg
        den = M + m * c * c
        common = p.alpha * math.sin(w * t) - C * yd - K * y - k3 * y**3 - m * l * thd * thd * c + s * fd / l
        return [yd, (common + m * g * s * s) / den, thd, -(s / l) * (common + (M + m) * g) / den - fd / (m * l * l)]

    sol = solve_ivp(rhs, (0.0, periods / p.fe), state0, method="RK45", rtol=1e-8, atol=1e-10)
    return sol.y[:, -1]


@benchmark("core")
def bench_core(quick: bool) -> dict:
    """ns per RK4 step, the Fig. 11(a) sweep, and solve_ivp on the same points."""
    backend = make_backend("emulated")
    state = backend.initial_state(FIG9_PO, 0, 0, 0.1, 0)
    periods = 20 if quick else 120
    backend.run_point(FIG9_PO, state, 1, 1)  # compile / load the cache
    steps = periods * backend.steps_per_period(FIG9_PO)
    t_point = best_of(lambda: backend.run_point(FIG9_PO, state, periods - 20 if periods > 20 else 0, 20), 5)

    spec = load_sweep(SWEEPS / "fig11a.toml")
    config = spec.config
    if quick:
        config = replace(config, values=config.values[::10])
    n_points = len(config.values)
    t_sweep = best_of(lambda: run_sweep(config, None, n_jobs=1), 1 if quick else 3)

    # solve_ivp is slow: time a few points and scale to the sweep's point count.
    sample = config.values[:: max(1, n_points // (2 if quick else 4))]
    ivp_periods = 10 if quick else periods
    t_ivp = best_of(
        lambda: [solve_ivp_point(config.params_at(v), [0.0, 0.0, 0.1, 0.0], ivp_periods) for v in sample], 1
    )
    t_ivp_sweep = t_ivp / len(sample) * n_points * (config.transient_periods + config.record_periods) / ivp_periods
    return {
        "ns_per_rk4_step_single_point": 1e9 * t_point / steps,
        "fig11a_points": n_points,
        "fig11a_periods_per_point": config.transient_periods + config.record_periods,
        "fig11a_sweep_seconds_one_core": t_sweep,
        "fig11a_target_seconds": 2.0,
        "solve_ivp_rk45_rtol1e-8_sweep_seconds_estimated": t_ivp_sweep,
        "solve_ivp_points_timed": len(sample),
        "solve_ivp_periods_timed": ivp_periods,
        "speedup_vs_solve_ivp": t_ivp_sweep / t_sweep,
    }
