"""Throughput of the batched kernel against its peers, measured side by side.

All peers integrate the same points (a Fig. 10(b)-like grid: alpha x M at
fe = 2.5 Hz, 400 RK4 steps of 1 ms per forcing period) and are reported as
ns per point-step per core, point-steps per second per core, and how many
times slower than the batched kernel they are. "Per core" is measured as
process CPU time (all threads), which stays meaningful on a shared, loaded
machine where wall time does not; wall times are reported alongside. A "point-step" is one 1 ms
RK4 step of one parameter point; solve_ivp (adaptive RK45) is charged per
1 ms of simulated time. Each peer runs a horizon long enough to time
reliably and is scaled per point-step (stated in ``horizon_periods``).

Also: the Fig. 10(a) grid (100 omega_hat x 100 alpha x 120 periods) end to
end, throughput against batch size and thread count (plotted to
``results/figures/throughput.png``), and what LLVM made of the inner loop.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np

from ..backends import make_backend
from ..backends._batch import run_batch
from ..kernels import WIDE_VECTORS, wrap_angle
from ..model.params import TABLE_IV, ModelParams
from .core import solve_ivp_point
from .lane_loop import TARGETS_ISA, target_environment, vector_instructions, vector_instructions_for
from .registry import benchmark

FIGURE = Path("results/figures/throughput.png")
TARGETS = {
    "batched_ns_per_point_step_per_core_max": 6.0,
    "avx2_build_ns_per_point_step_per_core_max": 10.0,
    "speedup_vs_scalar_min": 5.0,
    "speedup_vs_jax_min": 10.0,
    "speedup_vs_solve_ivp_min": 1000.0,
    "fig10a_grid_seconds_max": 60.0,
}


def peer_points(n_alpha: int, n_mass: int) -> list[ModelParams]:
    """alpha in [0, 40] N x M in [5.9, 20.9] kg (Fig. 10(b)'s masses) at fe = 2.5 Hz."""
    return [TABLE_IV.replace(alpha=a, M=M) for M in np.linspace(5.9, 20.9, n_mass) for a in np.linspace(0, 40, n_alpha)]


def fig10a_points(n_omega: int, n_alpha: int) -> list[ModelParams]:
    """omega_hat in [0.9, 1.1] x alpha in [0, 40] N, Table IV otherwise."""
    fe_per_omega_hat = 2.0 * TABLE_IV.omega_p / (2.0 * math.pi)
    return [
        TABLE_IV.replace(alpha=a, fe=w * fe_per_omega_hat)
        for w in np.linspace(0.9, 1.1, n_omega)
        for a in np.linspace(0, 40, n_alpha)
    ]


def _columns(params: list[ModelParams]) -> tuple[np.ndarray, ...]:
    """Per-point parameter columns ``m, l, b1, b2, b3, g, M, C, K, k3, alpha, omega_e``."""
    p = np.stack([q.kernel_array() for q in params], axis=1)
    return (*p, np.array([q.alpha for q in params]), np.array([q.omega_e for q in params]))


def rk4_step_for(xp):
    """One RK4 step of Eq. (11) written against an array module (numpy or jax.numpy).

    This is a peer, the script a user would write without pendsweep, so it is
    deliberately an independent implementation: it shares no code with the
    kernels (numpy and JAX cannot call numba functions anyway).

    ``step(cols, z, t, dt)``: ``cols`` are the per-point columns of
    :func:`_columns`, ``z`` the stacked state ``(4, ...)``; the signum of
    thetadot is held over the step, the forcing is ``alpha sin(omega_e t)``.
    """

    def rhs(cols, z, force, sg):
        m, l, b1, b2, b3, g, M, C, K, k3 = cols[:10]
        y, yd, th, thd = z
        s, c = xp.sin(th), xp.cos(th)
        fd = b1 * sg + b2 * thd + b3 * thd * thd * sg
        den = M + m * c * c
        common = force - C * yd - K * y - k3 * y**3 - m * l * thd * thd * c + s * fd / l
        return xp.stack(
            [yd, (common + m * g * s * s) / den, thd, -(s / l) * (common + (M + m) * g) / den - fd / (m * l * l)]
        )

    def step(cols, z, t, dt):
        alpha, w = cols[10], cols[11]
        sg = xp.sign(z[3])
        fh = alpha * xp.sin(w * (t + 0.5 * dt))
        k1 = rhs(cols, z, alpha * xp.sin(w * t), sg)
        k2 = rhs(cols, z + 0.5 * dt * k1, fh, sg)
        k3 = rhs(cols, z + 0.5 * dt * k2, fh, sg)
        k4 = rhs(cols, z + dt * k3, alpha * xp.sin(w * (t + dt)), sg)
        return z + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)

    return step


def numpy_rk4(params: list[ModelParams], states: np.ndarray, n_steps: int, dt: float) -> np.ndarray:
    """Plain numpy RK4 of Eq. (11), vectorised across points; returns the ``(n, 4)`` final states."""
    cols = _columns(params)
    step = rk4_step_for(np)
    z = states.T.copy()
    for k in range(n_steps):
        z = step(cols, z, k * dt, dt)
    return z.T


def jax_rk4_factory():
    """A jitted ``f(params, states, n_steps, dt)``: JAX vmap over points of a lax.scan RK4 (float64)."""
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    step = rk4_step_for(jnp)

    def point(cols, z0, n_steps, dt):
        return jax.lax.scan(lambda z, k: (step(cols, z, k * dt, dt), None), z0, jnp.arange(n_steps))[0]

    batched = jax.jit(jax.vmap(point, in_axes=(1, 0, None, None)), static_argnums=(2,))

    def run(params, states, n_steps, dt):
        cols = jnp.asarray(np.stack(_columns(params)))
        return np.array(batched(cols, jnp.asarray(states), n_steps, dt).block_until_ready())

    return run


def best_times(fn: Callable[[], Any], repeat: int = 3) -> tuple[float, float]:
    """Smallest wall time and smallest process CPU time (all threads) [s] of ``repeat`` calls."""
    walls, cpus = [], []
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    return min(walls), min(cpus)


def _row(
    name: str, times: tuple[float, float], point_steps: float, threads: int, horizon: float, note: str = ""
) -> dict:
    wall, cpu = times
    ns = 1e9 * cpu / point_steps
    return {
        "peer": name,
        "threads": threads,
        "ns_per_point_step_per_core": ns,
        "point_steps_per_s_per_core": 1e9 / ns,
        "wall_ns_per_point_step": 1e9 * wall / point_steps,
        "horizon_periods": horizon,
        "note": note,
    }


_NARROW_SCRIPT = """
import json, sys
import numpy as np
from pendsweep.backends._batch import run_batch
from pendsweep.bench.throughput import best_times, peer_points
n_alpha, n_mass, horizon, threads = (int(a) for a in sys.argv[1:])
params = peer_points(n_alpha, n_mass)
states = np.tile([0.0, 0.0, 0.1, 0.0], (len(params), 1))
run_batch(params, states, 0, 1)
print(json.dumps(best_times(lambda: run_batch(params, states, 0, horizon, threads=threads), 5)))
"""


def _build_row(name: str, env: dict[str, str], grid: tuple[int, int], horizon: int, threads: int, note: str) -> dict:
    """The batched kernel on the peers' points, built and timed in a fresh process with environment ``env``."""
    done = subprocess.run(
        [sys.executable, "-c", _NARROW_SCRIPT, *(str(v) for v in (*grid, horizon, threads))],
        env=env, capture_output=True, text=True, check=True,
    )  # fmt: skip
    times = json.loads(done.stdout.strip().splitlines()[-1])
    name = f"{name} ({threads} thread{'s' if threads > 1 else ''})"
    return _row(name, times, grid[0] * grid[1] * horizon * 400, threads, horizon, note)


def _narrow_vectors_row(grid: tuple[int, int], horizon: int, threads: int) -> dict | None:
    """The batched kernel built with numba's own tuning (256-bit vectors), in a fresh process.

    The peer of :mod:`pendsweep.kernels._vector_width`: the same points and horizon; None
    where this process does not use 512-bit vectors (nothing to compare).
    """
    if not WIDE_VECTORS:
        return None
    env = dict(os.environ, PENDSWEEP_VECTOR_WIDTH="256")
    return _build_row(
        "pendsweep batched, numba's 256-bit tuning",
        env,
        grid,
        horizon,
        threads,
        "PENDSWEEP_VECTOR_WIDTH=256, a fresh process",
    )


def _avx2_row(grid: tuple[int, int], horizon: int, threads: int) -> dict | None:
    """The batched kernel built for AVX2 (``TARGETS_ISA["avx2"]``) and run here, in a fresh process and numba cache.

    What an AVX2-only machine runs, timed on this one: None where this CPU
    lacks AVX2 or is that build already (no AVX-512).
    """
    import llvmlite.binding as llvm

    features = llvm.get_host_cpu_features().flatten().split(",")
    if "+avx2" not in features or "+avx512f" not in features:
        return None
    with tempfile.TemporaryDirectory(prefix="pendsweep-avx2-") as cache:
        name, features = TARGETS_ISA["avx2"]
        return _build_row(
            "pendsweep batched, AVX2 build", target_environment("avx2", cache), grid, horizon, threads,
            f"NUMBA_CPU_NAME={name} NUMBA_CPU_FEATURES='{features}', a fresh process",
        )  # fmt: skip


def _markdown(rows: list[dict]) -> list[str]:
    lines = [
        "| peer | threads | ns / point-step / core (CPU) | point-steps / s / core | wall ns / point-step | slower than pendsweep batched |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        ratio = r.get("times_slower_than_batched")
        ratio_text = "-" if ratio is None else f"{ratio:,.1f}x"
        lines.append(
            f"| {r['peer']} | {r['threads']} | {r['ns_per_point_step_per_core']:,.1f} | "
            f"{r['point_steps_per_s_per_core']:.3g} | {r['wall_ns_per_point_step']:,.1f} | {ratio_text} |"
        )
    return lines


def _scaling(quick: bool) -> dict:
    """Throughput against batch size for 1 and 2 threads (uniform-fe points)."""
    sizes = [1, 4, 16, 64, 256] if quick else [1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096]
    threads = [t for t in (1, 2) if t <= nb.config.NUMBA_NUM_THREADS]
    budget = 2e5 if quick else 3e6  # point-steps per measurement
    out: dict = {"batch_sizes": sizes, "load_average": os.getloadavg()[0]}
    base = peer_points(64, 64)
    for t in threads:
        rates = []
        for n in sizes:
            params = [base[i % len(base)] for i in range(n)]
            periods = max(4, int(budget / (n * 400)))
            states = np.tile([0.0, 0.0, 0.1, 0.0], (n, 1))
            wall, _ = best_times(lambda p=params, s=states, k=periods, t=t: run_batch(p, s, 0, k, threads=t), 3)
            rates.append(n * periods * 400 / wall)
        out[f"point_steps_per_s_threads_{t}"] = rates
    return out


_HALF_GRID_SCRIPT = """
import sys, time
import numpy as np
from pendsweep.backends._batch import run_batch
from pendsweep.bench.throughput import fig10a_points
n_omega, n_alpha, periods, half = (int(a) for a in sys.argv[1:5])
grid = fig10a_points(n_omega, n_alpha)[half::2]
states = np.tile([0.0, 0.0, 0.1, 0.0], (len(grid), 1))
run_batch(grid[:16], states[:16], 0, 1, threads=1)  # load the kernel before the clock starts
print("ready", flush=True)
sys.stdin.readline()
t0 = time.perf_counter()
run_batch(grid, states, 0, periods, threads=1)
print(time.perf_counter() - t0, flush=True)
"""


def _process_ceiling(n_omega: int, n_alpha: int, periods: int) -> float:
    """Wall time [s] of the grid split over two single-thread processes started together.

    The peer of 2 numba threads with nothing shared: what the machine itself
    gives two cores running this kernel (caches, memory, frequency, and on a
    VM whatever else the host shares).
    """
    import subprocess

    argv = [sys.executable, "-c", _HALF_GRID_SCRIPT, str(n_omega), str(n_alpha), str(periods)]
    procs = [
        subprocess.Popen([*argv, str(h)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True) for h in (0, 1)
    ]
    try:
        for p in procs:
            if p.stdout.readline().strip() != "ready":
                raise RuntimeError("a half-grid process failed to start")
        for p in procs:
            p.stdin.write("go\n")
            p.stdin.flush()
        return max(float(p.stdout.readline()) for p in procs)
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait()


def _grid_scaling(quick: bool) -> dict:
    """The Fig. 10(a) grid on 1 and 2 threads, against two independent processes."""
    n_omega, n_alpha, periods = (10, 10, 4) if quick else (100, 100, 10)
    grid = fig10a_points(n_omega, n_alpha)
    states = np.tile([0.0, 0.0, 0.1, 0.0], (len(grid), 1))
    run_batch(grid[:16], states[:16], 0, 1)
    one, _ = best_times(lambda: run_batch(grid, states, 0, periods, threads=1), 2)
    two, _ = best_times(lambda: run_batch(grid, states, 0, periods, threads=2), 2)
    split = min(_process_ceiling(n_omega, n_alpha, periods) for _ in range(2))
    return {
        "points": len(grid),
        "periods": periods,
        "seconds_1_thread": one,
        "seconds_2_threads": two,
        "seconds_2_processes": split,
        "speedup_2_threads": one / two,
        "speedup_2_processes": one / split,
        "threads_over_processes": split / two,
        "load_average": os.getloadavg()[0],
    }


def _plot(scaling: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    sizes = scaling["batch_sizes"]
    keys = [k for k in scaling if k.startswith("point_steps_per_s_threads_")]  # one curve per thread count
    for k in keys:
        t = int(k.rsplit("_", 1)[1])
        axes[0].loglog(sizes, scaling[k], "o-", label=f"{t} thread{'s' if t > 1 else ''}")
    axes[0].set_xlabel("batch size [points]")
    axes[0].set_ylabel("point-steps per second")
    axes[0].set_title("Batched kernel: throughput vs batch size")
    axes[0].grid(True, which="both", alpha=0.3)
    axes[0].legend()
    grid = scaling.get("grid")
    if grid:  # speedups on the Fig. 10(a) grid, with what two independent processes get
        labels = ["1 thread", "2 threads", "2 processes\n(no sharing)"]
        speedups = [1.0, grid["speedup_2_threads"], grid["speedup_2_processes"]]
        axes[1].bar(labels, speedups, color=["C0", "C1", "C7"])
        axes[1].axhline(2.0, color="k", ls="--", label="linear scaling")
        for x, v in enumerate(speedups):
            axes[1].text(x, v + 0.03, f"{v:.2f}x", ha="center")
        axes[1].set_ylabel("speedup over 1 thread")
        axes[1].set_title(
            f"{grid['points']:,} points (load average {grid['load_average']:.1f}, {os.cpu_count()} cores)"
        )
        axes[1].legend(loc="lower right")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=150)
    plt.close(fig)


@benchmark("throughput")
def bench_throughput(quick: bool) -> dict:
    """Batched kernel vs scalar kernel, numpy RK4, JAX and solve_ivp on the same points."""
    threads = nb.config.NUMBA_NUM_THREADS
    grid = (8, 4) if quick else (16, 16)
    params = peer_points(*grid)
    n = len(params)
    steps = 400  # fe = 2.5 Hz at dt = 1 ms
    dt = 1.0 / (2.5 * steps)
    states = np.tile([0.0, 0.0, 0.1, 0.0], (n, 1))
    rows = []

    horizon = 4 if quick else 20
    run_batch(params, states, 0, 1)  # compile / load the cache
    for t in sorted({1, threads}):
        times = best_times(lambda t=t: run_batch(params, states, 0, horizon, threads=t), 5)
        rows.append(
            _row(f"pendsweep batched ({t} thread{'s' if t > 1 else ''})", times, n * horizon * steps, t, horizon)
        )

    # Against the one-thread row: no scheduling in the ratios.
    builds = [_narrow_vectors_row(grid, horizon, 1), _avx2_row(grid, horizon, 1)]
    rows.extend(row for row in builds if row is not None)

    backend = make_backend("emulated")
    backend.run_point(params[0], states[0], 0, 1)
    h_scalar = 1 if quick else 5
    times = best_times(lambda: [backend.run_point(p, s, 0, h_scalar) for p, s in zip(params, states)], 3)
    rows.append(_row("pendsweep scalar kernel", times, n * h_scalar * steps, 1, h_scalar))

    h_numpy = 1 if quick else 2
    times = best_times(lambda: numpy_rk4(params, states, h_numpy * steps, dt), 1 if quick else 3)
    rows.append(_row("numpy RK4, vectorised across points", times, n * h_numpy * steps, 1, h_numpy))
    agreement = {
        "numpy_rk4_vs_batched_final_state_max_abs_diff_after_1_period": float(
            np.max(np.abs(numpy_rk4(params, states, steps, dt) - run_batch(params, states, 0, 1).states))
        )
    }

    try:
        jax_run = jax_rk4_factory()
    except ImportError:
        jax_note = "jax not installed: pip install 'pendsweep[bench]' to add this peer"
        print(f"throughput: JAX row skipped ({jax_note})", file=sys.stderr)
    else:
        import jax

        jax_run(params, states, horizon * steps, dt)  # compile
        times = best_times(lambda: jax_run(params, states, horizon * steps, dt), 3)
        rows.append(
            _row(
                f"JAX {jax.__version__} vmap + lax.scan RK4, float64, CPU",
                times,
                n * horizon * steps,
                threads,
                horizon,
                "XLA's own thread pool; CPU time of all its threads",
            )
        )
        z = jax_run(params, states, steps, dt)
        z[:, 2] = [wrap_angle(v) for v in z[:, 2]]  # the kernels rewrap theta every period
        agreement["jax_rk4_vs_batched_final_state_max_abs_diff_after_1_period"] = float(
            np.max(np.abs(z - run_batch(params, states, 0, 1).states))
        )
        jax_note = "measured"

    # Forced points spread over the grid (alpha = 0 alone would flatter the adaptive solver).
    ivp_points = params[n // 8 :: max(1, n // (2 if quick else 4))]
    h_ivp = 1
    times = best_times(lambda: [solve_ivp_point(p, [0.0, 0.0, 0.1, 0.0], h_ivp) for p in ivp_points], 1)
    rows.append(
        _row(
            "scipy solve_ivp RK45 rtol 1e-8, per point",
            times,
            len(ivp_points) * h_ivp * steps,
            1,
            h_ivp,
            f"{len(ivp_points)} points x {h_ivp} period, charged per 1 ms of simulated time",
        )
    )

    best = min(
        r["ns_per_point_step_per_core"]
        for r in rows
        if r["peer"].startswith("pendsweep batched") and "256-bit" not in r["peer"] and "AVX2" not in r["peer"]
    )
    for r in rows:
        r["times_slower_than_batched"] = r["ns_per_point_step_per_core"] / best
    by_name = {r["peer"].split(" (")[0].split(",")[0]: r for r in rows}

    result: dict = {
        "load_average_1min_at_start": os.getloadavg()[0],
        "cpu_count": os.cpu_count(),
        "points": n,
        "steps_per_period": steps,
        "numba_threads": threads,
        "rows": rows,
        "table_markdown": _markdown(rows),
        "agreement": agreement,
        "jax": jax_note,
        "vector_instructions_of_inner_loop": vector_instructions(),
        "vector_instructions_by_isa": {isa: vector_instructions_for(isa) for isa in TARGETS_ISA},
        "wide_vectors": WIDE_VECTORS,
        "targets": TARGETS,
        "batched_ns_per_point_step_per_core": best,
        "speedup_vs_scalar": by_name["pendsweep scalar kernel"]["times_slower_than_batched"],
        "speedup_vs_solve_ivp": by_name["scipy solve_ivp RK45 rtol 1e-8"]["times_slower_than_batched"],
    }
    narrow_rows = [r for r in rows if "256-bit" in r["peer"]]
    if narrow_rows:
        one_thread = next(r for r in rows if r["peer"] == "pendsweep batched (1 thread)")
        result["speedup_vs_256_bit_vectors"] = (
            narrow_rows[0]["ns_per_point_step_per_core"] / one_thread["ns_per_point_step_per_core"]
        )
    avx2_rows = [r for r in rows if "AVX2" in r["peer"]]
    if avx2_rows:
        one_thread = next(r for r in rows if r["peer"] == "pendsweep batched (1 thread)")
        result["avx2_build_ns_per_point_step_per_core"] = avx2_rows[0]["ns_per_point_step_per_core"]
        result["avx2_build_over_host_build"] = (
            avx2_rows[0]["ns_per_point_step_per_core"] / one_thread["ns_per_point_step_per_core"]
        )
    jax_rows = [r for r in rows if r["peer"].startswith("JAX")]
    if jax_rows:
        result["speedup_vs_jax"] = jax_rows[0]["times_slower_than_batched"]

    fig10a = fig10a_points(10, 10) if quick else fig10a_points(100, 100)
    periods = (5, 1) if quick else (100, 20)
    run_batch(fig10a[:1], states[:1], 0, 1)
    wall, cpu = best_times(lambda: run_batch(fig10a, np.tile([0.0, 0.0, 0.1, 0.0], (len(fig10a), 1)), *periods), 1)
    result["fig10a_grid"] = {
        "points": len(fig10a),
        "periods_per_point": sum(periods),
        "seconds": wall,
        "cpu_seconds": cpu,
        "threads": threads,
        "point_steps": float(sum(sum(periods) * backend.steps_per_period(p) for p in fig10a)),
    }

    scaling = _scaling(quick)
    if nb.config.NUMBA_NUM_THREADS >= 2:
        scaling["grid"] = _grid_scaling(quick)
    result["scaling"] = scaling
    _plot(scaling, FIGURE)
    result["figure"] = str(FIGURE)
    return result
