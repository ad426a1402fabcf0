#!/usr/bin/env bash
# The GPU checks in one run, for a machine with an NVIDIA GPU where numba-cuda, numpy, pandas, pyarrow,
# scipy, click, joblib, tqdm and pytest are installed (no pip install: such machines may be offline).
#
#   OUT=folder bash scripts/gpu-check.sh
#
# Writes into OUT (default results/gpu-check): env.txt (GPU, driver, versions), tests.log (the real-GPU
# tests of tests/test_cuda.py, which CI without a GPU skips), bench.json and bench.log
# (`python -m pendsweep.bench gpu`). GPU_CHECK_SECONDS (default 420) bounds the whole run; the
# benchmark gets what the tests leave. Exit status: the tests' (the benchmark records its own failures).
set -u
cd "$(dirname "$0")/.."
out=${OUT:-results/gpu-check}
mkdir -p "$out"
py=${PYTHON:-python3}
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1 MPLBACKEND=Agg
deadline=$(($(date +%s) + ${GPU_CHECK_SECONDS:-420}))
left() { echo $((deadline - $(date +%s))); }

{
  date -u
  nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.sm,clocks.max.sm --format=csv
  echo "cpu cores: $(nproc); $(grep -m1 'model name' /proc/cpuinfo)"
  $py -c 'import sys; from importlib.metadata import distributions
names = {"numba", "numba-cuda", "numba_cuda", "numpy", "pandas", "pyarrow", "jax", "jaxlib", "cuda-bindings"}
print("python", sys.version.split()[0], *sorted(f"{d.name} {d.version}" for d in distributions() if d.name.lower() in names))'
} >"$out/env.txt" 2>&1
cat "$out/env.txt"

t0=$(date +%s)
limit=$(left)
((limit > 200)) && limit=200
timeout "$limit" $py -m pytest -q -rA -s -p no:cacheprovider tests/test_cuda.py -k "real_gpu or compiles" \
  >"$out/tests.log" 2>&1
tests_rc=$?
echo "tests: exit $tests_rc in $(($(date +%s) - t0)) s"
grep -E '^\{|passed|failed|error|skipped' "$out/tests.log" | tail -20

t0=$(date +%s)
timeout "$(left)" $py -m pendsweep.bench gpu -o "$out/bench.json" >"$out/bench.log" 2>&1
echo "bench: exit $? in $(($(date +%s) - t0)) s"
grep '^gpu bench' "$out/bench.log" | cut -c1-600
exit $tests_rc
