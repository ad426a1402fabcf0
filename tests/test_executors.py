"""Sweeps on a real dask.distributed LocalCluster: same bytes as local, survives a lost worker."""

import os
import signal
import threading
import time

import numpy as np
import pandas as pd
import pytest

from pendsweep.engine.executors import SCHEDULER_ENV, DaskExecutor, make_executor
from pendsweep.engine.results import read_results
from pendsweep.errors import ConfigError
from pendsweep.kernels import RECORD_COLUMNS
from pendsweep.studies.sweep import SweepConfig, run_sweep

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


def _data_bytes(df):
    return {c: df[c].to_numpy().tobytes() for c in ["point", "start", "period", *RECORD_COLUMNS]}


def test_dask_executor_gives_the_local_bytes(client):
    config = SweepConfig(
        "alpha", (5.0, 15.0, 25.0, 35.0), mode="multistart", starts=3, seed=1, transient_periods=20, record_periods=4
    )
    local = run_sweep(config, task_points=4)
    remote = run_sweep(config, executor=DaskExecutor(client), task_points=4)
    assert _data_bytes(remote) == _data_bytes(local)
    pd.testing.assert_frame_equal(remote, local, check_exact=True)
    # A continue branch is one task on a worker; its state carrying is unchanged.
    branch = SweepConfig("alpha", (18.0, 22.0), direction="both", transient_periods=10, record_periods=3)
    pd.testing.assert_frame_equal(run_sweep(branch, executor=DaskExecutor(client)), run_sweep(branch), check_exact=True)


def test_killed_worker_costs_only_its_chunk(client, tmp_path):
    config = SweepConfig(
        "alpha", tuple(np.linspace(10.0, 40.0, 24)), mode="fresh", transient_periods=600, record_periods=5
    )
    out = tmp_path / "scan.parquet"
    finished = {}

    def scan():
        finished["df"] = run_sweep(config, out, executor=DaskExecutor(client), task_points=3)

    runner = threading.Thread(target=scan)
    runner.start()
    victim = None
    deadline = time.time() + 60
    while victim is None and time.time() < deadline and runner.is_alive():
        busy = [w for w, tasks in client.processing().items() if tasks]
        victim = busy[0] if busy else None
        time.sleep(0.01)
    assert victim is not None, "no worker ever got a task"
    pid = client.run(os.getpid, workers=[victim])[victim]
    os.kill(pid, signal.SIGKILL)  # mid-task: the nanny restarts it, the scheduler reruns its task
    killed_mid_scan = runner.is_alive()
    runner.join(timeout=240)
    assert killed_mid_scan and victim not in client.scheduler_info()["workers"]
    assert not runner.is_alive()
    stored, _ = read_results(out)
    assert not stored.duplicated(["direction", "point", "start", "period"]).any()
    assert len(stored) == 24 * 5 and set(stored["point"]) == set(range(24))
    reference = run_sweep(config, task_points=3)
    assert _data_bytes(stored) == _data_bytes(reference)


def test_executor_choice_errors(monkeypatch):
    monkeypatch.delenv(SCHEDULER_ENV, raising=False)
    with pytest.raises(ConfigError, match="needs a scheduler"):
        make_executor("dask")
    with pytest.raises(ConfigError, match="choose one of local, dask"):
        make_executor("ray")
    with pytest.raises(ConfigError, match="--executor dask only"):
        make_executor("local", "tcp://127.0.0.1:8786")
    monkeypatch.setenv(SCHEDULER_ENV, "tcp://127.0.0.1:9")  # nothing listens there
    with pytest.raises(ConfigError, match="cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'"):
        DaskExecutor(timeout="1s")


def test_cli_sweep_on_the_cluster(client, tmp_path, monkeypatch):
    from click.testing import CliRunner

    from pendsweep.cli import main

    common = [
        "alpha",
        "--from",
        "10",
        "--to",
        "30",
        "--step",
        "10",
        "--mode",
        "fresh",
        "--transient-periods",
        "10",
        "--record-periods",
        "3",
        "--no-progress",
    ]
    runner = CliRunner()
    local = runner.invoke(main, [*common, "-o", str(tmp_path / "local.parquet")])
    assert local.exit_code == 0, local.output
    monkeypatch.setenv(SCHEDULER_ENV, client.scheduler.address)
    remote = runner.invoke(main, [*common, "--executor", "dask", "-o", str(tmp_path / "dask.parquet")])
    assert remote.exit_code == 0, remote.output
    a, _ = read_results(tmp_path / "local.parquet")
    b, _ = read_results(tmp_path / "dask.parquet")
    assert _data_bytes(a) == _data_bytes(b)
    monkeypatch.delenv(SCHEDULER_ENV)
    bad = runner.invoke(main, [*common, "--executor", "dask", "-o", str(tmp_path / "x.parquet")])
    assert bad.exit_code == 2 and "needs a scheduler" in bad.output


def test_hopf_scan_on_the_cluster(client):
    from pendsweep.studies.hopf import HopfConfig, run_hopf

    config = HopfConfig(omega_hat=(0.95, 1.0, 1.05), masses=(10.9,), methods=("analytic", "floquet"))
    remote = run_hopf(config, executor=DaskExecutor(client))
    pd.testing.assert_frame_equal(remote, run_hopf(config), check_exact=True)
