"""Benchmark registry: ``make bench`` (``python -m pendsweep.bench``).

A benchmark is ``f(quick: bool) -> dict`` of JSON-able measured numbers,
registered with :func:`benchmark`. Speed is reported as ratios against peers
measured in the same run, because absolute timings on a shared machine vary.
JIT compilation is always excluded: each benchmark warms its kernels first.
"""

from . import (  # noqa: F401  (registers the benchmarks)
    basins,  # noqa: F401  (basins and map against their kernel, issue 23)
    cluster,  # noqa: F401  (a basin map on 1 and 2 Dask workers, issue 23)
    command,  # noqa: F401  (whole commands against a plain script)
    continuation,  # noqa: F401  (continuation against finite differences and sweeps)
    core,  # noqa: F401  (registers benchmarks)
    curves,  # noqa: F401  (two-parameter curves against Floquet grids; the hybrid PD against a fine sweep)
    diagnosis,  # noqa: F401  (diagnosis on independent records)
    gpu,  # noqa: F401  (the CUDA kernel; skipped without a GPU)
    hopf,  # noqa: F401  (Hopf-boundary scans)
    measured,  # noqa: F401  (registers benchmarks)
    rig_sweep,  # noqa: F401  (the Fig. 11(a) sweep through a site in one continuous test, against a null site)
    rigs,  # noqa: F401  (diagnosis of servo-rig records part by part, issue 22)
    site,  # noqa: F401  (hybrid tests: OpenSees against pendsweep site and a naive site)
    substructured,  # noqa: F401  (registers benchmarks)
    throughput,  # noqa: F401  (batched kernel against its peers)
)
from .registry import BENCHMARKS, benchmark, best_of, run_benchmarks

__all__ = ["BENCHMARKS", "benchmark", "best_of", "run_benchmarks"]
