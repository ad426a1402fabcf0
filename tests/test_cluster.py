"""Dask as a cluster user runs it: a `dask scheduler` and `dask worker` processes on 127.0.0.1.

Unlike tests/test_executors.py (an in-process LocalCluster whose client is the
default one), pendsweep here reaches the scheduler only through its address,
as ``--executor dask --scheduler tcp://HOST:PORT`` does.
"""

import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from pendsweep.cli import main
from pendsweep.engine.executors import DaskExecutor
from pendsweep.engine.results import read_results
from pendsweep.kernels import RECORD_COLUMNS
from pendsweep.studies.sweep import SweepConfig, run_sweep

distributed = pytest.importorskip("distributed")
DASK = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")
pytestmark = pytest.mark.skipif(DASK is None, reason="the dask command line is not installed")
SRC = str(Path(__file__).resolve().parents[1] / "src")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _stop(proc: subprocess.Popen) -> None:
    """End a process group we started: SIGTERM, then SIGKILL after 15 s."""
    if proc.poll() is not None:
        return
    os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=15)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """``(address, client)`` of a scheduler and two single-threaded workers, each its own process."""
    logs = tmp_path_factory.mktemp("dask")
    address = f"tcp://127.0.0.1:{_free_port()}"
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    commands = {
        "scheduler": [DASK, "scheduler", "--host", "127.0.0.1", "--port", address.rsplit(":", 1)[1], "--no-dashboard"],
        "worker": [
            DASK,
            "worker",
            address,
            "--nworkers",
            "2",
            "--nthreads",
            "1",
            "--host",
            "127.0.0.1",
            "--no-dashboard",
            "--death-timeout",
            "60",
        ],
    }
    procs, client = [], None
    try:
        for name, cmd in commands.items():
            with open(logs / f"{name}.log", "wb") as log:
                procs.append(
                    subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
                )
        client = distributed.Client(address, timeout="60s", set_as_default=False)
        client.wait_for_workers(2, timeout=120)
        yield address, client
    finally:
        if client is not None:
            client.close()
        for proc in reversed(procs):
            _stop(proc)


def _record_bytes(df):
    return {c: df[c].to_numpy().tobytes() for c in ["point", "start", "period", *RECORD_COLUMNS]}


def test_cli_sweep_and_hopf_on_the_cluster_equal_local_runs(cluster, tmp_path):
    address, _ = cluster
    runner = CliRunner()
    # The failing command (shorter): a multistart sweep through --scheduler.
    sweep = [
        "alpha",
        "--from",
        "30",
        "--to",
        "45",
        "--step",
        "5",
        "--mode",
        "multistart",
        "--starts",
        "8",
        "--transient-periods",
        "30",
        "--record-periods",
        "5",
        "--no-progress",
    ]
    local = runner.invoke(main, [*sweep, "-o", str(tmp_path / "local.parquet")])
    remote = runner.invoke(
        main, [*sweep, "--executor", "dask", "--scheduler", address, "-o", str(tmp_path / "dask.parquet")]
    )
    assert local.exit_code == 0 and remote.exit_code == 0, remote.output
    a, b = read_results(tmp_path / "local.parquet")[0], read_results(tmp_path / "dask.parquet")[0]
    assert _record_bytes(a) == _record_bytes(b)
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    hopf = [
        "hopf",
        "--what",
        "0.95,1.0,1.05",
        "--method",
        "analytic,floquet,simulate",
        "--periods",
        "40",
        "--no-progress",
    ]
    local = runner.invoke(main, [*hopf, "-o", str(tmp_path / "hl.parquet")])
    remote = runner.invoke(
        main, [*hopf, "--executor", "dask", "--scheduler", address, "-o", str(tmp_path / "hd.parquet")]
    )
    assert local.exit_code == 0 and remote.exit_code == 0, remote.output
    a, b = read_results(tmp_path / "hl.parquet")[0], read_results(tmp_path / "hd.parquet")[0]
    assert (a["status"] == "ok").all() and len(a) == 9
    pd.testing.assert_frame_equal(a, b, check_exact=True)


def test_worker_killed_mid_run_costs_only_its_task(cluster, tmp_path):
    address, client = cluster
    config = SweepConfig(
        "alpha", tuple(np.linspace(10.0, 40.0, 12)), mode="fresh", transient_periods=1500, record_periods=4
    )
    out = tmp_path / "scan.parquet"
    finished = {}

    def scan():
        finished["df"] = run_sweep(config, out, executor=DaskExecutor(address), task_points=2)

    runner = threading.Thread(target=scan, daemon=True)
    runner.start()
    victim, deadline = None, time.time() + 120
    while victim is None and time.time() < deadline and runner.is_alive():
        busy = [w for w, tasks in client.processing().items() if tasks]
        victim = busy[0] if busy else None
        time.sleep(0.01)
    assert victim is not None, "no worker ever got a task"
    pid = client.run(os.getpid, workers=[victim])[victim]
    os.kill(pid, signal.SIGKILL)  # its nanny starts a new worker; the scheduler reruns the task elsewhere
    killed_mid_scan = runner.is_alive()
    runner.join(timeout=240)
    assert killed_mid_scan and not runner.is_alive()
    stored, _ = read_results(out)
    assert not stored.duplicated(["direction", "point", "start", "period"]).any()
    reference = run_sweep(config, task_points=2)
    assert _record_bytes(stored) == _record_bytes(reference)
    pd.testing.assert_frame_equal(finished["df"], reference, check_exact=True)
