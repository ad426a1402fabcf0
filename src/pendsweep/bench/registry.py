"""The benchmark registry: :func:`benchmark` registers a benchmark; :func:`run_benchmarks` runs them into bench.json."""

from __future__ import annotations

import json
import platform
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

BenchFn = Callable[[bool], dict[str, Any]]
BENCHMARKS: dict[str, BenchFn] = {}


def benchmark(name: str) -> Callable[[BenchFn], BenchFn]:
    """Decorator registering a benchmark under ``name``."""

    def deco(fn: BenchFn) -> BenchFn:
        BENCHMARKS[name] = fn
        return fn

    return deco


def best_of(fn: Callable[[], Any], repeat: int = 3) -> float:
    """Smallest wall time [s] of ``repeat`` calls (the least disturbed one)."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def run_benchmarks(names: list[str] | None, output: Path, quick: bool = False) -> dict[str, Any]:
    """Run benchmarks, merge their results into ``output`` (JSON) and return them."""
    from ..errors import ConfigError

    names = names or list(BENCHMARKS)
    unknown = [n for n in names if n not in BENCHMARKS]
    if unknown:
        raise ConfigError(f"unknown benchmark(s) {', '.join(unknown)}; choose from {', '.join(BENCHMARKS)}")
    report: dict[str, Any] = json.loads(output.read_text()) if output.exists() else {}
    report["machine"] = {
        "platform": platform.platform(),
        "processor": platform.processor(),
        "python": platform.python_version(),
    }
    for name in names:
        report[name] = BENCHMARKS[name](quick)
        report[name]["measured"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(json.dumps(report, indent=2, sort_keys=True))
    return report
