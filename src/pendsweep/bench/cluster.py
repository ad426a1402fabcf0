"""A basin map through ``--executor dask`` on 1 and on 2 local single-threaded workers (entry ``dask``).

Starts a ``dask scheduler`` and ``dask worker`` processes on 127.0.0.1 (as
tests/test_cluster.py does), runs ``pendsweep basins --grid NxN`` against
them as a client process and reports, per worker count: wall time, starts
per second per worker, the client's peak resident memory, the 2/1 scaling
and the time a 1000 x 1000 map would take at the measured rate. Without the
``dask`` command line the entry says so.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .registry import benchmark

DASK = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(proc: subprocess.Popen) -> None:
    """End a process group this script started."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def run(workers: int, grid: int, max_periods: int, folder: Path) -> dict:
    """One basin map on ``workers`` single-threaded workers; its timings and the client's peak RSS."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    # One numba thread per worker: the batched kernel would otherwise use every core in each worker.
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    cluster = [
        [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
        [DASK, "worker", address, "--nworkers", str(workers), "--nthreads", "1", "--host", "127.0.0.1"]
        + ["--no-dashboard", "--death-timeout", "60"],
    ]
    procs = []
    try:
        for cmd in cluster:
            log = open(folder / f"{cmd[1]}-{workers}.log", "wb")  # noqa: SIM115 (kept open for the process)
            procs.append(subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True))
        time.sleep(5)  # the workers register with the scheduler; the client waits for it as well
        output = folder / f"basins-{workers}.parquet"
        command = [sys.executable, "-m", "pendsweep.cli", "basins", "--alpha", "40", "--fe", "2.5"]
        command += ["--grid", f"{grid}x{grid}", "--max-periods", str(max_periods), "--jobs", "1"]
        command += ["--executor", "dask", "--scheduler", address, "-o", str(output), "--yes", "--no-progress"]
        t0 = time.perf_counter()
        client = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(client.pid, 0)
        wall = time.perf_counter() - t0
        text = client.stdout.read().decode()
        if status:
            raise RuntimeError(f"pendsweep basins failed:\n{text}")
    finally:
        for proc in reversed(procs):
            _stop(proc)
    starts = grid * grid
    return {
        "workers": workers,
        "starts": starts,
        "wall_s": round(wall, 2),
        "starts_per_s_per_worker": round(starts / wall / workers, 1),
        "client_peak_rss_mib": round(usage.ru_maxrss / 1024, 1),  # ru_maxrss is in KiB on Linux
        "summary": text.strip().splitlines()[0],
    }


@benchmark("dask")
def bench_dask(quick: bool) -> dict:
    """Starts per second per worker on 1 and 2 local workers, the 2/1 scaling and the client's peak memory."""
    if DASK is None:
        return {"note": "the dask command line is not installed: pip install 'pendsweep[cluster]'"}
    grid, max_periods = (100, 100) if quick else (300, 200)
    with tempfile.TemporaryDirectory() as folder:
        runs = [run(workers, grid, max_periods, Path(folder)) for workers in (1, 2)]
    one, two = runs
    return {
        "grid": f"{grid}x{grid}",
        "max_periods": max_periods,
        "load_average_1min_at_start": os.getloadavg()[0],
        "runs": runs,
        "scaling_2_over_1": one["wall_s"] / two["wall_s"],
        # The wall time includes start-up and the final merge, so the estimate errs on the long side.
        "estimated_1000x1000_s_on_2_workers": 1e6 / (two["starts_per_s_per_worker"] * 2),
    }
