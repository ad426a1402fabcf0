"""Hopf-boundary scans: a 25 x 4 Floquet scan and a simulated 25-point boundary."""

from __future__ import annotations

import numpy as np

from ..backends import make_backend
from ..model.params import TABLE_IV
from ..studies.hopf import HopfConfig, run_hopf
from .registry import benchmark, best_of


@benchmark("hopf")
def bench_hopf(quick: bool) -> dict:
    """Floquet scan over (omega_hat, M) and simulated bisection boundary at M = 10.9 kg on 2 workers."""
    n_omega = 5 if quick else 25
    omega_hat = tuple(np.linspace(0.88, 1.12, n_omega))
    masses = (5.9, 10.9, 15.9, 20.9)
    floquet = HopfConfig(omega_hat=omega_hat, masses=masses, methods=("floquet",))
    analytic = HopfConfig(omega_hat=omega_hat, masses=masses, methods=("analytic",))
    simulate = HopfConfig(omega_hat=omega_hat, methods=("simulate",))
    backend = make_backend("emulated")
    backend.run_point(TABLE_IV, backend.initial_state(TABLE_IV, 0, 0, 0.1, 0), 1, 1)  # load the JIT cache
    run_hopf(HopfConfig(omega_hat=(1.0,), methods=("floquet",)))

    t_floquet = best_of(lambda: run_hopf(floquet, n_jobs=1), 1 if quick else 3)
    t_analytic = best_of(lambda: run_hopf(analytic, n_jobs=1), 1 if quick else 3)
    rows = run_hopf(simulate, n_jobs=2)
    t_simulate = best_of(lambda: run_hopf(simulate, n_jobs=2), 1)
    # The same number of simulated periods as one plain run, to show the protocol's overhead.
    periods = int((rows["runs"] * (simulate.periods + simulate.settle_periods + 1)).sum())
    state = backend.initial_state(TABLE_IV, 0, 0, 0.01, 0)
    t_raw = best_of(lambda: backend.run_point(TABLE_IV, state, periods - 1, 1), 1)
    return {
        "floquet_scan_points": n_omega * len(masses),
        "floquet_scan_seconds_one_core": t_floquet,
        "floquet_scan_target_seconds": 10.0,
        "floquet_over_analytic_time": t_floquet / t_analytic,
        "simulated_boundary_points": n_omega,
        "simulated_boundary_tol_N": simulate.tol,
        "simulated_boundary_runs_per_point": float(rows["runs"].mean()),
        "simulated_boundary_seconds_two_workers": t_simulate,
        "simulated_boundary_target_seconds": 60.0,
        "simulated_periods_total": periods,
        "simulated_over_one_plain_run_of_same_periods": t_simulate / t_raw,
    }
