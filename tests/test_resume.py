"""Crash safety of every scan: one writer per output, verified parts, bit-identical resume after SIGKILL."""

import json
import logging
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pendsweep.engine.results import OutputLock, OutputLocked, ResultStore, read_metadata, read_results
from pendsweep.engine.scan import check_jobs
from pendsweep.errors import ConfigError, ResultsError
from pendsweep.kernels import RECORD_COLUMNS
from pendsweep.studies.hopf import HopfConfig, run_hopf
from pendsweep.studies.sweep import SweepConfig, SweepScan, run_sweep, sweep_metadata, value_range

SRC = str(Path(__file__).resolve().parents[1] / "src")
ENV = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
CLI = [sys.executable, "-m", "pendsweep.cli"]
HOPF_NUMBERS = [
    "omega_hat",
    "fe",
    "M",
    "alpha_H",
    "multiplier",
    "growth_below",
    "growth_above",
    "bracket_lo",
    "bracket_hi",
    "kick",
    "runs",
]


def _parts(out: Path) -> list[Path]:
    return sorted(out.with_name(out.name + ".parts").glob("part-*.parquet"))


def _kill_after_parts(args: list[str], out: Path, min_parts: int = 1) -> None:
    """Start a real `pendsweep` process, SIGKILL it once ``min_parts`` parts exist, check it died mid-run."""
    # a part per unit: the kill lands mid-run however fast the machine
    proc = subprocess.Popen(
        CLI + args + ["--checkpoint-seconds", "0"], env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    deadline = time.time() + 120
    while time.time() < deadline and len(_parts(out)) < min_parts and proc.poll() is None:
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert len(_parts(out)) >= min_parts and not out.exists(), "the scan should have been killed mid-run"
    assert out.with_name(out.name + ".lock").exists()  # a dead holder's lock stays behind ...


def _resume(args: list[str], out: Path) -> pd.DataFrame:
    done = subprocess.run(CLI + args, env=ENV, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "took over the stale lock" in done.stderr  # ... and the next run takes it over
    assert not out.with_name(out.name + ".parts").exists() and not out.with_name(out.name + ".lock").exists()
    return read_results(out)[0]


def _record_bytes(df: pd.DataFrame) -> dict[str, bytes]:
    return {c: df[c].to_numpy().tobytes() for c in ["point", "start", "period", *RECORD_COLUMNS]}


@pytest.mark.parametrize(
    "mode_args, config",
    [
        # 480 fresh points: two batched tasks (256 + 224); the kill lands in the second.
        (
            ["--from", "0", "--to", "20", "--points", "480", "--mode", "fresh", "--record-periods", "4"],
            SweepConfig(
                "alpha", tuple(value_range(0, 20, points=480)), mode="fresh", transient_periods=300, record_periods=4
            ),
        ),
        # 13 points x 36 seeded starts: two batched tasks (256 + 212).
        (
            [
                "--from",
                "20",
                "--to",
                "26",
                "--step",
                "0.5",
                "--mode",
                "multistart",
                "--starts",
                "36",
                "--seed",
                "1",
                "--record-periods",
                "10",
            ],
            SweepConfig(
                "alpha",
                tuple(value_range(20, 26, 0.5)),
                mode="multistart",
                starts=36,
                seed=1,
                transient_periods=300,
                record_periods=10,
            ),
        ),
    ],
    ids=["fresh", "multistart"],
)
def test_killed_sweep_resumes_bit_identical(tmp_path, mode_args, config):
    out = tmp_path / "killed.parquet"
    args = ["alpha", *mode_args, "--transient-periods", "300", "-j", "1", "-o", str(out), "--no-progress"]
    _kill_after_parts(args, out)
    resumed = _resume(args, out)
    reference = run_sweep(config)
    assert not resumed.duplicated(["direction", "point", "start", "period"]).any()
    assert _record_bytes(resumed) == _record_bytes(reference)
    pd.testing.assert_frame_equal(resumed, reference, check_exact=True)


def test_killed_hopf_scan_resumes_bit_identical(tmp_path):
    out = tmp_path / "hopf.parquet"
    args = [
        "hopf",
        "--what",
        "0.9:1.1:140",
        "--method",
        "simulate",
        "--periods",
        "40",
        "-j",
        "1",
        "-o",
        str(out),
        "--no-progress",
    ]
    _kill_after_parts(args, out)
    resumed = _resume(args, out)
    config = HopfConfig(omega_hat=tuple(value_range(0.9, 1.1, points=140)), methods=("simulate",), periods=40)
    reference = run_hopf(config)
    assert len(resumed) == 140 and not resumed.duplicated(["mass_point", "point", "method"]).any()
    for column in HOPF_NUMBERS:
        assert resumed[column].to_numpy().tobytes() == reference[column].to_numpy().tobytes(), column
    pd.testing.assert_frame_equal(resumed, reference, check_exact=True)


def _partial_run(config: SweepConfig, out: Path, units: list[tuple[int, int]], task_points: int = 8) -> None:
    """Leave ``out`` as a kill would: parts holding only ``units`` of an uninterrupted run.

    Parts hold three units each (no timed checkpoint in between, however slow the machine).
    """
    scan = SweepScan(config, task_points)
    full = run_sweep(config, task_points=task_points)
    store = ResultStore(out, sweep_metadata(config), scan.row_columns, flush_points=3, flush_seconds=3600.0)
    for point, start in units:
        rows = full[(full.point == point) & (full.start == start)].reset_index(drop=True)
        store.add(rows, f"none:{point}:{start}", [])
    store.flush()
    store.close()


def test_a_finished_unit_is_written_while_the_next_one_runs(tmp_path):
    """The checkpoint interval bounds how long a finished unit waits in memory, even when no
    further unit arrives (before, it waited for the next unit, however long that took)."""
    config = SweepConfig("alpha", (10.0, 12.0), mode="fresh", transient_periods=5, record_periods=2)
    scan = SweepScan(config, 8)
    full = run_sweep(config)
    out = tmp_path / "timer.parquet"
    first, second = (full[full.point == k].reset_index(drop=True) for k in (0, 1))
    store = ResultStore(out, sweep_metadata(config), scan.row_columns, flush_seconds=2.0)
    store.add(first, "none:0:0", [])
    assert not _parts(out)  # within the interval of the store's start: buffered, a timer set
    deadline = time.time() + 30
    while not _parts(out) and time.time() < deadline:
        time.sleep(0.01)
    assert len(_parts(out)) == 1  # written by the timer; nothing else was called
    store.add(second, "none:1:0", [])
    store.close()  # the second unit is dropped with the store, as a kill would
    resumed = run_sweep(config, out)
    pd.testing.assert_frame_equal(resumed, full, check_exact=True)


@pytest.mark.parametrize("value", [-1.0, math.nan, math.inf, "1"])
def test_checkpoint_interval_is_checked(tmp_path, value):
    config = SweepConfig("alpha", (10.0,), transient_periods=5, record_periods=2)
    with pytest.raises(ConfigError, match="--checkpoint-seconds"):
        run_sweep(config, tmp_path / "x.parquet", checkpoint_seconds=value)


def test_resume_reruns_a_partly_done_chunk_whole(tmp_path):
    """Units resumed out of a half-finished batched task are integrated beside the same neighbours.

    Chaotic multistart points (the issue's 36-42 N) amplify any difference; resuming the last
    5 units of a 16-unit task in a task of their own changed theta by radians before.
    """
    config = SweepConfig(
        "alpha", (36.0, 40.0), mode="multistart", starts=16, seed=1, transient_periods=40, record_periods=6
    )
    out = tmp_path / "partial.parquet"
    _partial_run(config, out, [(0, s) for s in range(11)], task_points=16)
    resumed = run_sweep(config, out, task_points=16)
    reference = run_sweep(config, task_points=16)
    assert _record_bytes(resumed) == _record_bytes(reference)
    pd.testing.assert_frame_equal(resumed, reference, check_exact=True)


def test_corrupt_part_is_reported_and_its_units_redone(tmp_path, caplog):
    config = SweepConfig(
        "alpha", (10.0, 12.0, 14.0), mode="multistart", starts=3, transient_periods=20, record_periods=3
    )
    out = tmp_path / "corrupt.parquet"
    _partial_run(config, out, [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2), (2, 0)])
    parts = _parts(out)
    assert len(parts) == 3
    parts[1].write_bytes(b"PAR1 not really parquet")  # not the first part
    with caplog.at_level(logging.WARNING, logger="pendsweep"):
        resumed = run_sweep(config, out, task_points=8)
    assert any("unreadable" in r.message and parts[1].name in r.message for r in caplog.records)
    pd.testing.assert_frame_equal(resumed, run_sweep(config, task_points=8), check_exact=True)


def test_parts_carry_the_hash_and_the_config_is_stored_once(tmp_path):
    config = SweepConfig("alpha", (10.0, 12.0, 14.0), mode="fresh", transient_periods=5, record_periods=2)
    out = tmp_path / "once.parquet"
    _partial_run(config, out, [(0, 0), (1, 0)])
    meta = sweep_metadata(config)
    stored = json.loads((out.with_name(out.name + ".parts") / "config.json").read_text())
    assert stored["config_hash"] == meta["config_hash"] and stored["config"] == meta["config"]
    for part in _parts(out):
        part_meta = read_metadata(part)
        assert (
            set(part_meta) == {"config_hash", "final_states", "units"}
            and part_meta["config_hash"] == meta["config_hash"]
        )
    # A part of another configuration among them is refused, not merged.
    other = SweepConfig(
        "alpha", (10.0, 12.0, 14.0), mode="fresh", model={"fe": 2.3}, transient_periods=5, record_periods=2
    )
    foreign = tmp_path / "foreign.parquet"
    _partial_run(other, foreign, [(2, 0)])
    _parts(foreign)[0].rename(out.with_name(out.name + ".parts") / "part-000099-1.parquet")
    with pytest.raises(ResultsError, match="part-000099-1.parquet.*different configuration"):
        run_sweep(config, out)


def test_finished_file_clears_leftover_parts(tmp_path):
    config = SweepConfig("alpha", (10.0, 12.0), transient_periods=5, record_periods=2)
    out = tmp_path / "done.parquet"
    first = run_sweep(config, out)
    parts = out.with_name(out.name + ".parts")
    parts.mkdir()  # as a kill right after the final rename leaves it
    (parts / "part-000000-1.parquet").write_bytes(b"stale")
    pd.testing.assert_frame_equal(run_sweep(config, out), first)
    assert not parts.exists()


def test_one_writer_per_output(tmp_path, caplog):
    out = tmp_path / "locked.parquet"
    meta = sweep_metadata(SweepConfig("alpha", (1.0,), transient_periods=5, record_periods=2))
    with ResultStore(out, meta, ["point"]):
        with pytest.raises(OutputLocked, match=rf"being written by pid {os.getpid()} on host {socket.gethostname()}"):
            ResultStore(out, meta, ["point"])
    # A lock file whose process is gone (no flock held) is stale: taken over, and said so.
    out.with_name(out.name + ".lock").write_text(json.dumps({"pid": 2**22 + 7, "host": "gone", "started": "then"}))
    with caplog.at_level(logging.WARNING, logger="pendsweep"):
        lock = OutputLock(out)
    assert lock.previous["pid"] == 2**22 + 7 and "took over the stale lock of pid 4194311" in caplog.text
    holder = json.loads(lock.path.read_text())
    assert holder["pid"] == os.getpid() and holder["host"] == socket.gethostname()
    lock.release()
    assert not lock.path.exists()


def test_second_process_is_refused_at_once(tmp_path):
    """The issue's race: two sweeps (same or other configuration) started into one output."""
    from click.testing import CliRunner

    from pendsweep.cli import main

    out = tmp_path / "shared.parquet"
    base = [
        "alpha",
        "--from",
        "0",
        "--to",
        "45",
        "--step",
        "0.5",
        "--transient-periods",
        "20000",
        "--record-periods",
        "10",
        "-j",
        "1",
        "-o",
        str(out),
        "--no-progress",
    ]
    first = subprocess.Popen(CLI + base, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    lock = out.with_name(out.name + ".lock")
    try:
        deadline = time.time() + 60
        while time.time() < deadline and not (lock.exists() and lock.read_text()) and first.poll() is None:
            time.sleep(0.01)
        assert first.poll() is None, "the first sweep should be running"
        for extra in ([], ["--fe", "2.3"]):  # the second command, run here: no need for a third process
            second = CliRunner().invoke(main, base + extra)
            assert second.exit_code == 2, second.output
            assert f"being written by pid {first.pid} on host {socket.gethostname()}" in second.output
            assert "Traceback" not in second.output and len(second.output.strip().splitlines()) == 1
        assert first.poll() is None, "the first sweep should still be running"
    finally:
        first.kill()
        first.wait()


def test_jobs_and_work_are_checked_before_anything_runs(tmp_path):
    for bad in (0, -2, 2000, 1.5):
        with pytest.raises(ConfigError, match="--jobs"):
            check_jobs(bad)
    config = SweepConfig("alpha", tuple(value_range(0, 45, 0.5)), mode="multistart", starts=64)
    # 91 points x 64 starts x 120 periods x 400 steps
    with pytest.raises(ConfigError, match=r"about 2.8e\+08 integration steps \(5824 runs x 120 periods x 400 steps\)"):
        run_sweep(config, tmp_path / "big.parquet", max_work=1e8)
    assert not (tmp_path / "big.parquet.lock").exists() and not (tmp_path / "big.parquet.parts").exists()
    with pytest.raises(ConfigError, match="at most 1000000"):
        value_range(0, 1e308, 1e300)


@pytest.mark.parametrize(
    "args, message",
    [
        (["alpha", "--from", "0", "--to", "4", "-j", "0"], "--jobs = 0"),
        (["hopf", "--what", "1", "--method", "analytic", "-j", "0"], "--jobs = 0"),
        (
            ["alpha", "--from", "0", "--to", "45", "--mode", "multistart", "--starts", "64", "--max-work", "1e8"],
            "pass --max-work 3e8 (or --yes)",
        ),
        (["hopf", "--what", "1:2:1000000"], "integration steps"),
        (["alpha", "--from", "0", "--to", "1e308", "--step", "1e300"], "100,000,001 values"),
    ],
)
def test_cli_refuses_without_hanging(tmp_path, args, message):
    from click.testing import CliRunner

    from pendsweep.cli import main

    result = CliRunner().invoke(main, [*args, "-o", str(tmp_path / "x.parquet"), "--no-progress"])
    assert result.exit_code == 2, result.output
    assert message in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_max_work_is_lifted_by_yes(tmp_path):
    from click.testing import CliRunner

    from pendsweep.cli import main

    args = [
        "alpha",
        "--from",
        "1",
        "--to",
        "2",
        "--transient-periods",
        "5",
        "--record-periods",
        "2",
        "--max-work",
        "10",
        "-o",
        str(tmp_path / "y.parquet"),
        "--no-progress",
    ]
    assert CliRunner().invoke(main, args).exit_code == 2
    result = CliRunner().invoke(main, [*args, "--yes"])
    assert result.exit_code == 0, result.output
    assert np.isfinite(read_results(tmp_path / "y.parquet")[0]["theta_absmax"]).all()


def test_worker_exception_reaches_the_caller():
    from pendsweep.engine.executors import LocalExecutor

    def good():
        yield from (1, 2)

    def bad():
        raise RuntimeError("worker failed")
        yield  # a generator, as tasks are

    with pytest.raises(RuntimeError, match="worker failed"):
        list(LocalExecutor().map_unordered([good, bad, good], 2))
    with pytest.raises(ValueError):  # the pool itself failing is raised too, never a hang
        list(LocalExecutor().map_unordered([good, good], 0))


def test_without_flock_the_pid_inside_decides(tmp_path, monkeypatch):
    """On a filesystem without flock, a live holder on this host still refuses and a dead one is taken over."""
    import errno
    import fcntl

    def no_flock(fd, op):
        raise OSError(errno.EOPNOTSUPP, "Operation not supported")

    monkeypatch.setattr(fcntl, "flock", no_flock)
    out = tmp_path / "nfs.parquet"
    lock_file = out.with_name(out.name + ".lock")
    sleeper = subprocess.Popen(["sleep", "30"])
    try:
        lock_file.write_text(json.dumps({"pid": sleeper.pid, "host": socket.gethostname()}))
        with pytest.raises(OutputLocked, match=f"pid {sleeper.pid}"):
            OutputLock(out)
    finally:
        sleeper.kill()
        sleeper.wait()
    lock = OutputLock(out)  # the holder is gone now
    assert lock.previous["pid"] == sleeper.pid
    lock.release()
