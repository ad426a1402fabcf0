"""Hybrid-test benchmark: OpenSees's genericClient against ``pendsweep site`` and against a naive site.

Ratios in one run: the same OpenSees model (``examples/opensees_pendulum_site.py``)
drives ``pendsweep site`` and the naive spring site of :mod:`.naive_site`; the
pendsweep client drives the site too, against the in-process substructured
point. ``--realtime`` is run for 60 s at 1 kHz (5 s with ``--quick``).
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .registry import benchmark

ALPHA, FE = 5.0, 2.2  # the Fig. 9 PO point
#: Issue 21's goals: 120 periods at 2.2 Hz (54,600 steps) in at most 14 s, p99 service at most 0.2 ms.
GOAL_SECONDS = 14.0
GOAL_P99_SERVICE = 2e-4


def start_site(*args: str, once: bool = True) -> tuple[subprocess.Popen, int]:
    """``pendsweep site`` on a free loopback port (one client with ``once``); (process, port)."""
    cmd = [sys.executable, "-m", "pendsweep.cli", "site", "--port", "0", *(("--once",) if once else ()), *args]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    for line in proc.stderr:
        found = re.search(r"listening on [\d.]+:(\d+)", line)
        if found:
            return proc, int(found.group(1))
    raise RuntimeError("pendsweep site did not start")


def _opensees_against_site(periods: int, *site_args: str) -> dict:
    from ..engine.columns import read_parquet, to_numpy
    from ..hybrid.opensees import run_example

    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "log.parquet"
        proc, port = start_site("-o", str(log), "--set", f"fe={FE}", *site_args)
        result = run_example(port, ALPHA, FE, periods)
        proc.communicate(timeout=120)
        table = read_parquet(log)
        service = to_numpy(table["service_time"])
        late = to_numpy(table["late"])
        t = to_numpy(table["t"])
        lag = to_numpy(table["wall"]) - t  # how far each trial arrived behind its simulated time
    service = service[np.isfinite(service)]
    return {
        "steps": int(t.size),
        "simulated_seconds": float(t[-1]),
        "opensees_wall_seconds": result["wall"],
        "steps_per_second": t.size / result["wall"],
        "times_real_time": float(t[-1]) / result["wall"],
        "service_p50_us": float(np.quantile(service, 0.5) * 1e6),
        "service_p99_us": float(np.quantile(service, 0.99) * 1e6),
        "service_max_us": float(service.max() * 1e6),
        "deadline_misses": int(late.sum()),
        "trial_arrival_lag_max_ms": float(lag.max() * 1e3),
    }


def _opensees_against_naive(periods: int) -> dict:
    from ..hybrid.opensees import run_example

    script = Path(__file__).with_name("naive_site.py")
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    port = int(proc.stdout.readline())
    result = run_example(port, ALPHA, FE, periods)
    proc.wait(timeout=60)
    steps = periods * round(1.0 / (FE * 1e-3))
    return {"opensees_wall_seconds": result["wall"], "steps_per_second": steps / result["wall"]}


def _client_against_site(periods: int) -> dict:
    from ..backends import make_backend
    from ..model.params import ModelParams

    params = ModelParams.from_mapping({"alpha": ALPHA, "fe": FE})
    proc, port = start_site("--set", f"fe={FE}", "-B", "actuator=servo")
    remote = make_backend("substructured", rig=f"tcp://127.0.0.1:{port}")
    start = time.perf_counter()
    run = remote.run_point(params, remote.initial_state(params, 0, 0, 0.1, 0), periods - 1, 1)
    wall = time.perf_counter() - start
    proc.communicate(timeout=60)
    local = make_backend("substructured")
    local.run_point(params, local.initial_state(params, 0, 0, 0.1, 0), 1, 1)  # warm
    start = time.perf_counter()
    local.run_point(params, local.initial_state(params, 0, 0, 0.1, 0), periods - 1, 1)
    local_wall = time.perf_counter() - start
    return {
        "status": run.status.value,
        "periods_done": run.periods_done,
        "wall_seconds": wall,
        "times_real_time": periods / FE / wall,
        "round_trip_p50_us": float(run.round_trip[0] * 1e6),
        "round_trip_p99_us": float(run.round_trip[1] * 1e6),
        "in_process_wall_seconds": local_wall,
        "ratio_remote_over_in_process": wall / local_wall,
    }


@benchmark("site")
def bench_site(quick: bool) -> dict:
    """Steps per second and service times of a hybrid test with OpenSees as the client (dt = 1 ms)."""
    from ..hybrid.opensees import EXAMPLE, opensees_library_dir

    if opensees_library_dir() is None or not EXAMPLE.exists():
        return {"skipped": "openseespy (the test extra) or examples/opensees_pendulum_site.py is missing"}
    periods = 20 if quick else 120
    site = _opensees_against_site(periods)
    naive = _opensees_against_naive(periods)
    realtime_periods = round((5.0 if quick else 60.0) * FE)
    realtime = _opensees_against_site(realtime_periods, "--realtime")
    client = _client_against_site(periods)
    return {
        "periods": periods,
        "opensees_pendsweep_site": site,
        "opensees_naive_site": naive,
        "ratio_pendsweep_site_faster_than_naive": naive["opensees_wall_seconds"] / site["opensees_wall_seconds"],
        "goal_wall_seconds_at_most": GOAL_SECONDS if not quick else None,
        "goal_service_p99_us_at_most": GOAL_P99_SERVICE * 1e6,
        "realtime": realtime,
        "pendsweep_client_against_site": client,
    }
