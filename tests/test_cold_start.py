"""A cold numba cache: one line says compiling has started, a warm one says nothing; `pendsweep warmup` warms every command."""

import os
import subprocess
import sys

from pendsweep.kernels._notice import MESSAGE

TWO_KERNELS = "from pendsweep.kernels import forcing_table, wrap_angle; wrap_angle(7.0); forcing_table(1.0, 4)"


def _run(argv, cache, cwd=None):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    return subprocess.run(argv, env=env, cwd=cwd, capture_output=True, text=True, check=True)


def test_a_cold_cache_prints_one_line_and_a_warm_one_nothing(tmp_path):
    cold = _run([sys.executable, "-c", TWO_KERNELS], tmp_path / "cache")
    assert cold.stderr.count(MESSAGE) == 1, cold.stderr  # two kernels compiled, one line
    warm = _run([sys.executable, "-c", TWO_KERNELS], tmp_path / "cache")
    assert MESSAGE not in warm.stderr, warm.stderr


def test_warmup_compiles_what_the_canonical_sweep_needs(tmp_path):
    """After `pendsweep warmup` in an empty cache, the canonical sweep compiles nothing."""
    cache = tmp_path / "cache"
    done = _run([sys.executable, "-m", "pendsweep.cli", "warmup"], cache, cwd=tmp_path)
    assert "failed" not in done.stderr, done.stderr
    sweep = [sys.executable, "-m", "pendsweep.cli", "alpha", "--from", "0", "--to", "45", "-o", "c.parquet"]
    first = _run(sweep, cache, cwd=tmp_path)
    assert MESSAGE not in first.stderr, first.stderr
