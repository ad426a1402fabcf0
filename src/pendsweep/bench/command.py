"""What a user waits for: whole commands, start-up included, against a plain script.

Each command runs in its own process, four times; the first compiles and
warms the caches, the fastest of the other three is taken, on both sides. The peer
is :mod:`pendsweep.bench.naive_sweep`, run as a plain file. Ratios are
from one run on one machine, side by side.

Python writes its bytecode caches, as on a default install, even where the
environment says not to (``PYTHONDONTWRITEBYTECODE``): recompiling the
package's 50 modules on every start would add 0.08 s that no user waits for.

No command can be faster than the start-up every numba program pays
(interpreter, numpy, numba, numba's first-call registry set-up, one cached
kernel): the naive script's one-point run measures it, so
``dense_ratio_ceiling`` (the dense script's time over it) bounds the dense
ratio any such command can reach, and ``dense_compute_ratio`` compares
the two with that start-up taken off both.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .registry import benchmark

NAIVE = Path(__file__).with_name("naive_sweep.py")


def wall_time(argv: list[str], cwd: Path, repeat: int = 3) -> float:
    """Smallest wall time [s] of ``repeat`` runs of ``argv`` after one that warms the caches.

    The least disturbed run: the dense ratio takes differences of start-ups
    of about 0.6 s, and one run each scattered it from 9 to 15 on this VM.
    """
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    times = []
    for _ in range(repeat + 1):
        t0 = time.perf_counter()
        subprocess.run(argv, cwd=cwd, check=True, capture_output=True, env=env)
        times.append(time.perf_counter() - t0)
    return min(times[1:])


def dense_evidence_per_point(step: float) -> dict:
    """Extension periods and Lyapunov pairs per point of the dense fresh sweep, staged and full evidence."""
    import numpy as np

    from ..classify import classify_runs
    from ..sweep import SweepConfig, value_range

    config = SweepConfig(parameter="alpha", values=tuple(value_range(0.0, 45.0, step)), mode="fresh")
    backend = config.make_backend()
    params = [config.params_at(v) for v in config.values]
    states = np.array([backend.initial_state(q, *config.initial) for q in params])
    runs = backend.run_points(params, states, config.transient_periods, config.record_periods)
    out = {}
    labels = {}
    for evidence in ("staged", "full"):
        motions = classify_runs(backend, params, runs, config.rest_threshold, evidence)
        labels[evidence] = [m.label for m in motions]
        out[f"dense_{evidence}_extension_periods_per_point"] = float(np.mean([m.extension_periods for m in motions]))
        out[f"dense_{evidence}_lyapunov_pairs_per_point"] = float(np.mean([m.lyapunov_pair for m in motions]))
    out["dense_labels_differing_staged_vs_full"] = sum(a != b for a, b in zip(labels["staged"], labels["full"]))
    return out


@benchmark("command")
def bench_command(quick: bool) -> dict:
    """``pendsweep --help``, the canonical sweep and the dense fresh sweep against the naive script."""
    pendsweep = [sys.executable, "-m", "pendsweep.cli"]
    naive = [sys.executable, str(NAIVE)]
    dense_step = "0.5" if quick else "0.05"
    dense = [*pendsweep, "alpha", "--from", "0", "--to", "45", "--step", dense_step, "--mode", "fresh"]
    dense += ["-o", "d.parquet", "--overwrite"]
    work = Path(tempfile.mkdtemp(prefix="pendsweep-bench-"))
    try:
        out = {
            "help_seconds": wall_time([*pendsweep, "--help"], work),
            "canonical_seconds": wall_time(
                [*pendsweep, "alpha", "--from", "0", "--to", "45", "-o", "c.parquet", "--overwrite"], work
            ),
            "canonical_naive_script_seconds": wall_time([*naive, "continue", "0", "45", "0.5"], work),
            # Start-up floors: a one-point sweep (120 periods, a few ms of integration), and imports alone.
            "one_point_seconds": wall_time(
                [*pendsweep, "alpha", "--from", "10", "--to", "10", "-o", "o.parquet", "--overwrite"], work
            ),
            "one_point_naive_script_seconds": wall_time([*naive, "continue", "10", "10", "1"], work),
            "import_seconds": wall_time([sys.executable, "-c", "import pendsweep.cli._sweep, pendsweep.sweep"], work),
            "import_numba_pyarrow_pandas_seconds": wall_time(
                [sys.executable, "-c", "import numba, pyarrow.parquet, pandas"], work
            ),
            "import_numba_seconds": wall_time([sys.executable, "-c", "import numba"], work),
            "dense_fresh_points": 901 if not quick else 91,
            "dense_fresh_seconds": wall_time([*dense, "--evidence", "staged"], work),
            # Before issue 23 item 2: every undecided point's whole extension and Lyapunov pair.
            "dense_fresh_full_evidence_seconds": wall_time([*dense, "--evidence", "full"], work),
            "dense_fresh_naive_script_seconds": wall_time([*naive, "fresh", "0", "45", dense_step], work),
        }
    finally:
        shutil.rmtree(work, ignore_errors=True)
    out["canonical_over_naive"] = out["canonical_seconds"] / out["canonical_naive_script_seconds"]
    out["dense_naive_over_pendsweep"] = out["dense_fresh_naive_script_seconds"] / out["dense_fresh_seconds"]
    floor = out["one_point_naive_script_seconds"]
    out["dense_ratio_ceiling"] = out["dense_fresh_naive_script_seconds"] / floor
    for evidence, key in (("", "dense_fresh_seconds"), ("_full_evidence", "dense_fresh_full_evidence_seconds")):
        out[f"dense_compute_ratio{evidence}"] = (out["dense_fresh_naive_script_seconds"] - floor) / max(
            out[key] - out["one_point_seconds"], 1e-9
        )
    out.update(dense_evidence_per_point(float(dense_step)))
    out["targets"] = {
        "help_seconds_max": 0.3,
        "one_point_seconds_max": 1.0,
        "canonical_over_naive_max": 1.5,
        "dense_naive_over_pendsweep_min": 10.0,
        "dense_compute_ratio_min": 10.0,
    }
    return out
