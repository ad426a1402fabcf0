"""Continuation (issue 15): monodromy by variational equations against finite differences, and a
whole Fig. 11(a) continuation against the brute-force sweep of the same range."""

from __future__ import annotations

import numpy as np

from ..analysis.continuation.run import ContinuationConfig, run_continuation
from ..analysis.continuation.shooting import PendulumShooting
from ..backends import make_backend
from ..model.params import TABLE_IV
from ..studies.hopf import hopf_floquet
from ..studies.sweep import SweepConfig, run_sweep, value_range
from .registry import benchmark, best_of


@benchmark("continuation")
def bench_continuation(quick: bool) -> dict:
    """Cost of one monodromy matrix, and of a continuation against a sweep over alpha 0-45 N (b1 = b3 = 0)."""
    smooth = {"fe": 2.5, "b1": 0.0, "b3": 0.0}
    params = TABLE_IV.replace(alpha=30.0, **smooth)
    problem = PendulumShooting(params, "alpha", period=2)
    x = np.array([-0.0145, -0.54, -0.93, -5.74])
    backend = make_backend("emulated")
    problem.evaluate(x, 30.0)  # load the JIT caches
    backend.run_point(params, x, 2, 1)

    repeat = 3 if quick else 20
    t_variational = best_of(lambda: [problem.evaluate(x, 30.0) for _ in range(repeat)]) / repeat

    def finite_differences():
        # The peer: central differences of the sweep kernel's map, 8 runs of 2 periods per matrix.
        for j in range(4):
            for sign in (1.0, -1.0):
                backend.run_point(params, x + sign * 1e-7 * problem.scale[j] * np.eye(4)[j], 1, 1)

    t_fd = best_of(lambda: [finite_differences() for _ in range(repeat)]) / repeat

    top = 20.0 if quick else 45.0
    config = ContinuationConfig("alpha", 0.0, top, smooth)
    run_continuation(config)
    t_cont = best_of(lambda: run_continuation(config), 1)
    doc = run_continuation(config)
    sweep = SweepConfig("alpha", tuple(value_range(0.0, top, 0.5)), model=smooth)
    t_sweep = best_of(lambda: run_sweep(sweep, n_jobs=1), 1)
    pd = next(b["value"] for b in doc["bifurcations"] if b["type"] == "period-doubling")
    floquet = hopf_floquet(TABLE_IV.replace(**smooth), steps=problem.steps)["alpha_H"]
    points = sum(len(b["points"]) for b in doc["branches"])
    return {
        "monodromy_seconds_variational": t_variational,
        "monodromy_seconds_finite_differences": t_fd,
        "monodromy_variational_over_finite_differences": t_variational / t_fd,
        "continuation_alpha_range_N": [0.0, top],
        "continuation_points": points,
        "continuation_seconds_one_core": t_cont,
        "sweep_points": len(sweep.values),
        "sweep_seconds_one_core": t_sweep,
        "continuation_over_sweep_time": t_cont / t_sweep,
        "period_doubling_N": pd,
        "period_doubling_relative_to_floquet": pd / floquet - 1.0,
    }
