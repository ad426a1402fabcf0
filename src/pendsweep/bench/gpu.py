"""The CUDA kernel against the CPU batched kernel and JAX on the same GPU (issue 16).

Runs only when a CUDA GPU is usable; otherwise the entry records
``"skipped: no CUDA device (...)"``. Measured, on the GPU it names:

* throughput in point-steps per second for >= 1e5 points (float64, and the
  opt-in float32) on the Fig. 10(b)-like alpha x M grid of the throughput
  benchmark (fe = 2.5 Hz, 400 steps of 1 ms per period), with the CPU
  batched kernel on the same points in the same run;
* JAX vmap + lax.scan RK4 (float64) on the same GPU when JAX sees one;
* headline timings: the Fig. 10(b) simulated Hopf grid (25 omega_hat x 4
  masses, bisection) on the GPU and on the CPU, and a 500 x 500 basin-style
  grid of fresh starts (theta0 x thetadot0 at the Fig. 11(a) parameters).

Kernel compilation is excluded: each configuration is launched once first.
"""

from __future__ import annotations

import time

import numpy as np

from ..backends._batch import run_batch
from ..gpu import cuda_unavailable_reason, device_name
from ..params import FIG11A
from .registry import benchmark, best_of
from .throughput import jax_rk4_factory, peer_points

TARGETS = {"float64_point_steps_per_s_min": 2e10, "speedup_vs_jax_same_gpu_min": 10.0}
STEPS = 400  # fe = 2.5 Hz at dt = 1 ms


def throughput(n_side: int, periods: int, precision: str) -> dict:
    """Point-steps per second of the GPU kernel on ``n_side**2`` points over ``periods`` periods."""
    params = peer_points(n_side, n_side)
    states = np.tile([0.0, 0.0, 0.1, 0.0], (len(params), 1))
    run_batch(params[:32], states[:32], 0, 1, device="cuda", precision=precision)  # compile
    wall = best_of(lambda: run_batch(params, states, 0, periods, device="cuda", precision=precision), 3)
    point_steps = len(params) * periods * STEPS
    return {
        "points": len(params),
        "periods": periods,
        "seconds": wall,
        "point_steps_per_s": point_steps / wall,
        "ps_per_point_step": 1e12 * wall / point_steps,
    }


def cpu_throughput(n_side: int, periods: int) -> dict:
    """The CPU batched kernel (all numba threads) on the same points."""
    params = peer_points(n_side, n_side)
    states = np.tile([0.0, 0.0, 0.1, 0.0], (len(params), 1))
    run_batch(params[:32], states[:32], 0, 1)
    wall = best_of(lambda: run_batch(params, states, 0, periods), 1)
    return {
        "points": len(params),
        "periods": periods,
        "seconds": wall,
        "point_steps_per_s": len(params) * periods * STEPS / wall,
    }


def jax_gpu(n_side: int, periods: int) -> dict:
    """JAX vmap + lax.scan RK4 in float64 on the same points, when JAX runs on a GPU."""
    try:
        import jax
    except ImportError:
        return {"skipped": "jax not installed: pip install 'pendsweep[bench]' (with a CUDA-enabled jaxlib)"}
    if jax.default_backend() != "gpu":
        return {"skipped": f"JAX runs on {jax.default_backend()!r}, not on the GPU"}
    run = jax_rk4_factory()
    params = peer_points(n_side, n_side)
    states = np.tile([0.0, 0.0, 0.1, 0.0], (len(params), 1))
    n_steps = periods * STEPS
    run(params, states, n_steps, 1.0 / (2.5 * STEPS))  # compile
    wall = best_of(lambda: run(params, states, n_steps, 1.0 / (2.5 * STEPS)), 3)
    return {
        "jax": jax.__version__,
        "device": str(jax.devices()[0]),
        "points": len(params),
        "periods": periods,
        "seconds": wall,
        "point_steps_per_s": len(params) * n_steps / wall,
    }


def hopf_grid(device: str, quick: bool) -> dict:
    """The Fig. 10(b) simulated Hopf grid (bisection in lockstep batches) on ``device``."""
    from ..figures.hopf import BIG_KICK, FIG10B_MASSES, OMEGA_HAT
    from ..hopf import HopfConfig, run_hopf

    omega_hat = tuple(np.linspace(*OMEGA_HAT, 4 if quick else 25))
    masses = FIG10B_MASSES[::3] if quick else FIG10B_MASSES
    config = HopfConfig(
        omega_hat=omega_hat, masses=masses, methods=("simulate",), kick=BIG_KICK, backend_options={"device": device}
    )
    run_hopf(HopfConfig(omega_hat=omega_hat[:1], methods=("simulate",), backend_options={"device": device}, periods=2))
    t0 = time.perf_counter()
    rows = run_hopf(config, n_jobs=1)
    return {
        "device": device,
        "rows": len(rows),
        "seconds": time.perf_counter() - t0,
        "alpha_H_mean_N": float(rows["alpha_H"].mean()),
    }


def basin_grid(n_side: int, transient: int, record: int) -> dict:
    """A basin-style grid of fresh starts: theta0 in (-pi, pi] x thetadot0 in [-10, 10] rad/s at Fig. 11(a)'s point."""
    theta, thetadot = np.meshgrid(np.linspace(-np.pi, np.pi, n_side), np.linspace(-10.0, 10.0, n_side))
    states = np.column_stack([np.zeros(theta.size), np.zeros(theta.size), theta.ravel(), thetadot.ravel()])
    params = [FIG11A] * len(states)
    run_batch(params[:32], states[:32], 0, 1, device="cuda")
    t0 = time.perf_counter()
    run = run_batch(params, states, transient, record, device="cuda")
    wall = time.perf_counter() - t0
    return {
        "grid": f"{n_side} x {n_side}",
        "periods": transient + record,
        "seconds": wall,
        "diverged": int((run.status != 0).sum()),
    }


@benchmark("gpu")
def bench_gpu(quick: bool) -> dict:
    """GPU kernel throughput, JAX on the same GPU, Fig. 10(b) Hopf grid and a 500 x 500 basin grid."""
    reason = cuda_unavailable_reason()
    if reason is not None:
        return {"skipped": f"no CUDA device ({reason})"}
    n_side = 100 if quick else 320  # 1e4 / 1.02e5 points
    periods = 5 if quick else 20
    f64 = throughput(n_side, periods, "float64")
    f32 = throughput(n_side, periods, "float32")
    cpu = cpu_throughput(40 if quick else 100, 2)
    jax_row = jax_gpu(n_side, 2)
    result = {
        "device": device_name(),
        "targets": TARGETS,
        "float64": f64,
        "float32": f32,
        "cpu_batched_same_points_all_threads": cpu,
        "jax_same_gpu": jax_row,
        "speedup_float64_vs_cpu_batched": f64["point_steps_per_s"] / cpu["point_steps_per_s"],
        "fig10b_hopf_grid_gpu": hopf_grid("cuda", quick),
        "fig10b_hopf_grid_cpu": hopf_grid("cpu", quick),
        "basin_grid_500x500": basin_grid(50 if quick else 500, 10 if quick else 100, 5 if quick else 20),
    }
    if "point_steps_per_s" in jax_row:
        result["speedup_float64_vs_jax_same_gpu"] = f64["point_steps_per_s"] / jax_row["point_steps_per_s"]
    return result
