"""The CUDA kernel against the CPU batched kernel and JAX on the same machine (issues 16 and 23).

Runs only when a CUDA GPU is usable; otherwise the entry records
``"skipped: no CUDA device (...)"``. Measured, on the GPU it names:

* kernel throughput in point-steps per second (float64, and the opt-in
  float32) on the Fig. 10(b)-like alpha x M grid of the throughput benchmark
  (fe = 2.5 Hz, 400 steps of 1 ms per period), at 102,400 points (under one
  wave of resident threads on an H100/H200) and at 1,048,576 points;
* the CPU batched kernel on the same kind of points, all cores of the same
  machine, in the same run;
* JAX vmap + lax.scan RK4 (float64) on the same GPU when JAX sees one;
* the Fig. 10(b) simulated Hopf grid (25 omega_hat x 4 masses, bisection)
  on the GPU and on the CPU;
* a 500 x 500 grid of fresh starts (every start to the same horizon);
* the basin map a user runs, ``pendsweep basins --alpha 40 --fe 2.5 --grid
  1000x1000 --max-periods 1000 --device cuda`` (rounds, settling checks and
  early stop, the result file written), and the 200 x 200 map on the CPU in
  the same run, both as ns per point-step actually integrated.

Kernel compilation is excluded: each configuration is launched once first.
Each part runs on its own: one that fails records a one-line ``failed``
reason and the others still run; a line per finished part goes to stderr.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..backends._base import steps_per_period
from ..backends._batch import run_batch
from ..backends.gpu import cuda_unavailable_reason, device_name
from ..model.params import FIG11A
from .registry import benchmark, best_of
from .throughput import jax_rk4_factory, peer_points

TARGETS = {"float64_point_steps_per_s_min": 2e10, "speedup_vs_jax_same_gpu_min": 10.0}
STEPS = 400  # fe = 2.5 Hz at dt = 1 ms


def throughput(n_side: int, periods: int, device: str = "cuda", precision: str = "float64", repeat: int = 3) -> dict:
    """Point-steps per second of the batched kernel on ``n_side**2`` points over ``periods`` periods.

    ``point_steps_per_s`` is the whole ``run_batch`` call (the parameter
    columns built, the transfers, the launch); ``kernel_point_steps_per_s``
    is the marginal cost of a period, from the same call with the columns
    built beforehand, run with and without ``periods`` extra transient
    periods (what the transfers and the host's work cost cancels out).
    """
    import numba

    from ..backends._batch import parameter_columns

    params = peer_points(n_side, n_side)
    states = np.tile([0.0, 0.0, 0.1, 0.0], (len(params), 1))
    options = {"device": device, "precision": precision}
    run_batch(params[:32], states[:32], 0, 1, **options)  # compile
    wall = best_of(lambda: run_batch(params, states, 0, periods, **options), repeat)
    columns = parameter_columns(params, 1e-3)
    short, long = (best_of(lambda t=t: run_batch(columns, states, t, 1, **options), repeat) for t in (0, periods))
    point_steps = len(params) * periods * STEPS
    return {
        "points": len(params),
        "periods": periods,
        **({"threads": numba.get_num_threads()} if device == "cpu" else {}),
        "seconds": wall,
        "point_steps_per_s": point_steps / wall,
        "ps_per_point_step": 1e12 * wall / point_steps,
        "kernel_point_steps_per_s": point_steps / (long - short),
        "kernel_ps_per_point_step": 1e12 * (long - short) / point_steps,
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
    from ..studies.hopf import HopfConfig, run_hopf

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
        "point_steps_per_s": len(states) * (transient + record) * steps_per_period(FIG11A.fe, 1e-3) / wall,
        "diverged": int((run.status != 0).sum()),
    }


def basin_map(n_side: int, max_periods: int, device: str, precision: str = "float64") -> dict:
    """``pendsweep basins --alpha 40 --fe 2.5 --grid NxN --max-periods P`` on ``device``, its result file written."""
    import pyarrow.parquet as pq

    from ..studies.basins import BasinConfig, run_basins

    config = BasinConfig(
        "alpha", (40.0,), {"fe": 2.5}, sampling="grid", grid=(n_side, n_side), max_periods=max_periods,
        backend_options={"device": device, "precision": precision},
    )  # fmt: skip
    params = config.params_at(40.0)
    run_batch([params] * 2, np.zeros((2, 4)), 0, 1, device=device, precision=precision)  # compile
    with tempfile.TemporaryDirectory() as folder:
        output = Path(folder) / "basins.parquet"
        t0 = time.perf_counter()
        run_basins(config, output, return_rows=False)
        wall = time.perf_counter() - t0
        table = pq.read_table(output, columns=["motion", "periods_done"])
    periods = table.column("periods_done").to_numpy()
    motion, counts = np.unique(table.column("motion").to_numpy(zero_copy_only=False).astype(str), return_counts=True)
    point_steps = float(periods.sum()) * steps_per_period(params.fe, 1e-3)
    return {
        "command": f"pendsweep basins --alpha 40 --fe 2.5 --grid {n_side}x{n_side} --max-periods {max_periods} "
        + (f"--device cuda -B precision={precision}" if device == "cuda" else "--device cpu"),
        "starts": config.starts,
        "wall_seconds": wall,
        "mean_periods_per_start": float(periods.mean()),
        "ns_per_point_step_wall": 1e9 * wall / point_steps,
        "motion_fractions": {str(m): float(c) / len(periods) for m, c in zip(motion, counts)},
    }


def _part(result: dict, name: str, fn: Callable[[], dict]) -> None:
    """Run one measurement into ``result[name]``; a failure is recorded in one line, the others still run."""
    t0 = time.perf_counter()
    try:
        result[name] = fn()
    except Exception as exc:  # a benchmark part that breaks must not lose the parts measured before it
        result[name] = {"failed": f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"}
    print(
        f"gpu bench: {name} ({time.perf_counter() - t0:.1f} s) {json.dumps(result[name], default=str)}",
        file=sys.stderr,
        flush=True,
    )


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    found = {}
    for name in ("numba", "numba-cuda", "numpy", "jax", "jaxlib"):
        try:
            found[name] = version(name)
        except PackageNotFoundError:
            found[name] = None
    return found


def _ratio(result: dict, a: str, b: str, key: str = "point_steps_per_s") -> float | None:
    """``result[a][key] / result[b][key]`` when both parts were measured."""
    if key in result.get(a, {}) and key in result.get(b, {}):
        return result[a][key] / result[b][key]
    return None


@benchmark("gpu")
def bench_gpu(quick: bool) -> dict:
    """GPU kernel throughput against the CPU kernel and JAX, the Fig. 10(b) Hopf grid, and basin maps."""
    reason = cuda_unavailable_reason()
    if reason is not None:
        return {"skipped": f"no CUDA device ({reason})"}
    n_side = 100 if quick else 320  # 1e4 / 1.02e5 points
    big_side = 200 if quick else 1024  # 4e4 / 1.05e6 points
    periods = 5 if quick else 20
    result: dict = {"device": device_name(), "versions": _versions(), "targets": TARGETS}
    _part(result, "float64", lambda: throughput(n_side, periods))
    _part(result, "float32", lambda: throughput(n_side, periods, precision="float32"))
    _part(result, "float64_1M_points", lambda: throughput(big_side, 2 if quick else 5))
    _part(result, "float32_1M_points", lambda: throughput(big_side, 2 if quick else 5, precision="float32"))
    _part(result, "cpu_batched_same_points_all_threads", lambda: throughput(n_side, 2, device="cpu", repeat=1))
    _part(result, "jax_same_gpu", lambda: jax_gpu(n_side, 2))
    cpu, e2e, kernel = "cpu_batched_same_points_all_threads", "point_steps_per_s", "kernel_point_steps_per_s"
    for name, a, b, key in (
        ("speedup_float64_vs_cpu_batched", "float64", cpu, e2e),
        ("kernel_speedup_float64_vs_cpu_batched", "float64", cpu, kernel),
        ("speedup_float64_1M_vs_cpu_batched", "float64_1M_points", cpu, e2e),
        ("speedup_float64_vs_jax_same_gpu", "float64", "jax_same_gpu", e2e),
        ("float32_over_float64", "float32", "float64", e2e),
        ("kernel_float32_over_float64", "float32", "float64", kernel),
    ):
        result[name] = _ratio(result, a, b, key)
    side, cap = (100, 300) if quick else (1000, 1000)
    _part(result, "basin_map_gpu", lambda: basin_map(side, cap, "cuda"))
    _part(result, "basin_map_gpu_float32", lambda: basin_map(side, cap, "cuda", "float32"))
    _part(result, "basin_map_cpu_same_machine", lambda: basin_map(50 if quick else 200, cap, "cpu"))
    result["basin_map_gpu_over_cpu_per_point_step"] = _ratio(
        result, "basin_map_cpu_same_machine", "basin_map_gpu", "ns_per_point_step_wall"
    )
    _part(
        result, "basin_grid_500x500", lambda: basin_grid(50 if quick else 500, 10 if quick else 100, 5 if quick else 20)
    )
    _part(result, "fig10b_hopf_grid_gpu", lambda: hopf_grid("cuda", quick))
    _part(result, "fig10b_hopf_grid_cpu", lambda: hopf_grid("cpu", quick))
    return result
