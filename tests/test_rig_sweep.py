"""The paper's experiment on a remote rig: continue sweeps through one session of a real socket.

Every test talks to a real ``pendsweep site`` (a subprocess, or a thread of
this process) on 127.0.0.1 through the OpenFresco protocol; nothing is
mocked. Noise-free sites make the remote rows comparable bit for bit with
the in-process substructured continue sweep.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from pendsweep.measured.records import read_record
from pendsweep.studies.rig_sweep import RigWatch
from pendsweep.studies.sweep import SweepConfig, run_sweep
from site_helpers import SiteProcess

#: The site's sensors without noise and the client's matching in-process loop (the site's default actuator: ideal).
QUIET_SITE = ("--set", "fe=2.5", "-B", "force_noise=0", "-B", "lvdt_noise=0")
QUIET_LOOP = dict(actuator="ideal", force_noise=0, lvdt_noise=0, harmonic3=0, harmonic5=0, harmonic7=0)
COMPARED = ["direction", "point", "period", "theta_peak", "theta_absmax", "y_sec", "ydot_sec", "theta_sec",
            "thetadot_sec", "y_absmax", "rotations", "status", "motion"]  # fmt: skip
SILENT = RigWatch(reference=False, echo=lambda line: None)


@pytest.fixture(scope="module")
def quiet_site(tmp_path_factory):
    log = tmp_path_factory.mktemp("site") / "site-log.parquet"
    site = SiteProcess(*QUIET_SITE, "-o", str(log))  # serves one client after another, each from its initial state
    site.log = log
    yield site
    status, err = site.stop()
    assert status == 0, err


def sessions_served(site, at_least: int = 0, timeout: float = 10.0) -> int:
    """Client sessions in the site's log (rewritten after each session ends), waiting for ``at_least``."""
    deadline = time.monotonic() + timeout
    while True:
        count = (
            len(set(pq.read_table(site.log, columns=["session"])["session"].to_pylist())) if site.log.exists() else 0
        )
        if count >= at_least or time.monotonic() > deadline:
            return count
        time.sleep(0.05)


def config(parameter="alpha", values=(15.0, 16.0, 17.0), **kw) -> dict:
    return dict(parameter=parameter, values=values, model={"fe": 2.5, "alpha": 17.0}, mode="continue",
                transient_periods=8, record_periods=3, kick=0.0, backend="substructured") | kw  # fmt: skip


@pytest.mark.parametrize(
    ("parameter", "values", "direction", "ramp"),
    [
        ("alpha", (15.0, 16.0, 17.0), "up", 0),
        ("alpha", (15.0, 16.0, 17.0), "down", 0),
        ("alpha", (15.0, 17.0), "both", 0),  # the hysteresis loop as one test
        ("alpha", (15.0, 16.0, 17.0), "up", 4),  # a ramp instead of a step
        ("fe", (1000 / 420, 1000 / 400), "up", 0),  # forcing periods of whole 1 ms ticks
    ],
)
def test_a_continuous_rig_test_equals_the_in_process_continue_sweep(quiet_site, parameter, values, direction, ramp):
    """One connection for the whole branch (both branches for ``both``): the rows are the in-process ones, bit for bit.

    In process, a rig's ``both`` is ``loop`` (the down branch starts where up ended).
    """
    rig = f"tcp://127.0.0.1:{quiet_site.port}"
    remote = SweepConfig(**config(parameter, values, direction=direction, ramp_periods=ramp,
                                  backend_options={"actuator": "ideal", "rig": rig}))  # fmt: skip
    local = SweepConfig(**config(parameter, values, direction="loop" if direction == "both" else direction,
                                 ramp_periods=ramp, backend_options=QUIET_LOOP))  # fmt: skip
    before = sessions_served(quiet_site)
    a, b = run_sweep(remote, watch=SILENT), run_sweep(local)
    assert a[COMPARED].equals(b[COMPARED])
    assert sessions_served(quiet_site, before + 1) == before + 1  # one session for the whole test
    assert not a["restarted"].any()


def run_cli(out: Path, rig: str, *extra: str, values=("--from", "15", "--to", "19", "--step", "1")):
    cmd = [sys.executable, "-m", "pendsweep.cli", "alpha", *values, "--fe", "2.5", "--mode", "continue",
           "--transient-periods", "12", "--record-periods", "4", "--backend", "substructured",
           "-B", "actuator=ideal", "-B", f"rig={rig}", "-o", str(out), *extra]  # fmt: skip
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_points(proc: subprocess.Popen, count: int, timeout: float = 120.0) -> list[str]:
    """Read the client's stderr until ``count`` per-point lines went by."""
    lines, deadline = [], time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        if not line:
            break
        lines.append(line)
        if sum(" theta_max " in x for x in lines) >= count:
            return lines
    raise AssertionError(f"the client printed {lines}")


def test_a_killed_client_resumes_in_a_new_session_with_nothing_lost_or_twice(quiet_site, tmp_path):
    out = tmp_path / "rig.parquet"
    rig = f"tcp://127.0.0.1:{quiet_site.port}"
    first = run_cli(out, rig)
    wait_for_points(first, 2)
    first.send_signal(signal.SIGKILL)
    first.wait()
    kept = pq.read_table(sorted(out.with_name(out.name + ".parts").glob("part-*.parquet"))).to_pandas()
    finished = sorted(kept["point"].unique().tolist())
    assert finished == [0, 1]  # a point is on disk before its line is printed
    second = run_cli(out, rig)
    _, err = second.communicate(timeout=300)
    assert second.returncode == 0, err
    assert "resuming at alpha" in err
    rows = pq.read_table(out).to_pandas()
    per_point = rows.groupby("point").agg(n=("period", "size"), restarted=("restarted", "first"))
    assert list(per_point["n"]) == [4] * 5  # every point once, whole
    restarted = per_point.index[per_point["restarted"]].tolist()
    assert restarted == [2]  # the first point of the new session: no point lost, none run twice
    series = pq.read_table(tmp_path / "rig-timeseries.parquet").to_pandas()
    # the killed session's ticks are there as far as its last flush (every 2 s: none if it ran shorter)
    assert set(series["session"].unique()) <= {0, 1} and series["session"].iloc[-1] == series["session"].max()
    assert not (tmp_path / "rig-timeseries.parquet.parts").exists()
    # the second session's ticks start again at the site's initial state: time restarts there
    last = series["session"].max()
    assert series.loc[series["session"] == last, "t"].iloc[0] == pytest.approx(0.0, abs=2e-3)


def test_sigint_mid_point_ramps_the_forcing_down_sends_die_and_exits_130(tmp_path):
    site = SiteProcess("--once", *QUIET_SITE, "-o", str(tmp_path / "site-log.parquet"))
    out = tmp_path / "rig.parquet"
    client = run_cli(out, f"tcp://127.0.0.1:{site.port}", "--stop-periods", "4")
    wait_for_points(client, 1)
    time.sleep(0.3)  # well inside the second point
    client.send_signal(signal.SIGINT)
    _, err = client.communicate(timeout=120)
    status, site_err = site.finish()
    assert client.returncode == 130, err
    assert "stopped by SIGINT; forcing ramped to zero over 4 periods, die sent" in err
    assert "Traceback" not in err
    assert status == 0 and "stopped:" not in site_err  # the site saw a normal die
    assert "the same command resumes" in err
    kept = pq.read_table(sorted(out.with_name(out.name + ".parts").glob("part-*.parquet"))).to_pandas()
    finished = sorted(kept["point"].unique().tolist())
    assert finished == list(range(len(finished))) and 1 <= len(finished) < 5  # for the resume; not the interrupted
    series = pq.read_table(tmp_path / "rig-timeseries.parquet").to_pandas()
    ramp = series[series["point"] < 0]  # the safe stop's periods
    period_ticks = 400
    assert len(ramp) >= 4 * period_ticks
    alpha = 15.0 + len(finished)  # the point that was running
    force = ramp["Fe"].to_numpy()[: 4 * period_ticks]
    envelope = alpha * (1.0 - np.arange(4 * period_ticks) / (4 * period_ticks))  # linear, tick by tick, to 0
    assert np.all(np.abs(force) <= envelope + 1e-9)
    peaks = [np.abs(force[k * period_ticks : (k + 1) * period_ticks]).max() for k in range(4)]
    assert peaks[0] > 0.7 * alpha and np.all(np.diff(peaks) < 0)
    command = series["command"].to_numpy()
    assert np.abs(np.diff(command)).max() < 2e-3  # continuous: no jump in the command anywhere
    # the same command again: a new session, the first one's time series kept
    site = SiteProcess("--once", *QUIET_SITE)
    rerun = run_cli(out, f"tcp://127.0.0.1:{site.port}", "--stop-periods", "4")
    _, err = rerun.communicate(timeout=300)
    assert rerun.returncode == 0 and site.finish()[0] == 0, err
    again = pq.read_table(tmp_path / "rig-timeseries.parquet").to_pandas()
    assert sorted(again["session"].unique()) == [0, 1]
    assert (again["session"] == 0).sum() == len(series)
    assert abs(again["command"].iloc[-1]) < 1e-6  # the test's end ramps down too: die at the actuator's centre


def test_a_limit_stops_the_test_with_a_whole_ramp_down(tmp_path):
    """The stroke limit trips mid-period: the ramp picks the forcing up at that phase and runs whole (no limit
    breaks a ramp), the site sees die; the point is kept as unstable, its finding."""
    site = SiteProcess("--once", *QUIET_SITE)
    out = tmp_path / "rig.parquet"
    client = run_cli(out, f"tcp://127.0.0.1:{site.port}", "-B", "stroke=0.015", "--stop-periods", "3",
                     values=("--from", "10", "--to", "17", "--step", "7"))  # fmt: skip
    _, err = client.communicate(timeout=300)
    status, site_err = site.finish()
    assert client.returncode == 1 and "stroke; forcing ramped to zero over 3 periods, die sent" in err, err
    assert status == 0 and "stopped:" not in site_err
    series = pq.read_table(tmp_path / "rig-timeseries.parquet").to_pandas()
    ramp = series[series["point"] < 0]
    assert len(ramp) >= 3 * 400 - 400  # the period broken off, then whole ones
    force = series["Fe"].to_numpy()
    assert np.abs(np.diff(force)).max() < 0.5  # 10 N at 400 ticks a period moves < 0.16 N a tick: no step to 0
    kept = pq.read_table(sorted(out.with_name(out.name + ".parts").glob("part-*.parquet"))).to_pandas()
    assert "unstable" in set(kept["status"])


def test_a_site_that_dies_mid_sweep_leaves_whole_files_and_exit_1(tmp_path):
    site = SiteProcess("--once", *QUIET_SITE)
    out = tmp_path / "rig.parquet"
    client = run_cli(out, f"tcp://127.0.0.1:{site.port}")
    wait_for_points(client, 1)
    site.proc.kill()
    _, err = client.communicate(timeout=120)
    assert client.returncode == 1, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("Error:") and "could not be ramped down" in last
    assert pq.read_table(next(out.with_name(out.name + ".parts").glob("part-*.parquet"))).num_rows >= 4
    record = read_record(tmp_path / "rig-timeseries.parquet")
    assert record.kind == "substructured" and len(record.data) > 4000


class GarbleProxy:
    """Forwards a client to a site, then replaces one reply with NaNs after ``good`` replies (a site gone wrong)."""

    REPLY_BYTES = 16 * 8  # the client's daq reply: 16 doubles

    def __init__(self, site_port: int, good: int) -> None:
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.site_port, self.good = site_port, good
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        client, _ = self.listener.accept()
        site = socket.create_connection(("127.0.0.1", self.site_port))
        threading.Thread(target=self._pipe, args=(client, site), daemon=True).start()
        sent = 0
        while True:
            data = site.recv(self.REPLY_BYTES - sent % self.REPLY_BYTES)
            if not data:
                break
            if sent // self.REPLY_BYTES >= self.good:
                data = np.full(len(data) // 8, np.nan).tobytes()
            client.sendall(data)
            sent += len(data)

    @staticmethod
    def _pipe(src: socket.socket, dst: socket.socket) -> None:
        while data := src.recv(65536):
            dst.sendall(data)


def test_a_site_that_answers_garbage_mid_sweep_stops_the_test_with_one_line(tmp_path):
    site = SiteProcess("--once", *QUIET_SITE)
    proxy = GarbleProxy(site.port, good=2 * 16 * 400 + 100)  # two points, then garbage inside the third
    out = tmp_path / "rig.parquet"
    client = run_cli(out, f"tcp://127.0.0.1:{proxy.port}")
    _, err = client.communicate(timeout=120)
    site.stop()
    assert client.returncode == 1, err
    last = err.strip().splitlines()[-1]
    assert "not finite or beyond" in last and "could not be ramped down" in last
    kept = pq.read_table(sorted(out.with_name(out.name + ".parts").glob("part-*.parquet"))).to_pandas()
    assert sorted(kept["point"].unique().tolist()) == [0, 1]
    assert pq.read_table(tmp_path / "rig-timeseries.parquet").num_rows >= 2 * 16 * 400


@pytest.mark.parametrize(
    ("args", "expect"),
    [
        (["sweep", "m", "--from", "0.2", "--to", "0.3", "--step", "0.05"], "m belongs to the physical substructure"),
        (["sweep", "C2", "--from", "5", "--to", "6", "--step", "1"], "C2 belongs to the physical substructure"),
        (["alpha", "--from", "4", "--to", "5", "--kick", "0.1"], "cannot be kicked from the client"),
        (["alpha", "--from", "4", "--to", "5", "--mode", "multistart"], "not multistart"),
        (["alpha", "--from", "4", "--to", "5", "--ramp", "200"], "the ramp is part of the transient"),
        (["alpha", "--from", "4", "--to", "5", "--mode", "fresh", "--ramp", "2"], "--ramp 2 applies only"),
    ],
)
def test_what_a_client_cannot_do_to_a_rig_exits_2_with_one_line(args, expect, tmp_path):
    cmd = [sys.executable, "-m", "pendsweep.cli", *args, "--backend", "substructured",
           "-B", "rig=tcp://127.0.0.1:9", "-o", str(tmp_path / "x.parquet")]  # fmt: skip
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=os.environ | {"COLUMNS": "200"})
    assert done.returncode == 2, done.stderr
    assert expect in done.stderr and len(done.stderr.strip().splitlines()) == 1


def test_transient_auto_through_a_rig_equals_the_in_process_one(quiet_site):
    """``--transient auto``: the next step comes when the record has settled (or at the cap), as in process."""
    rig = f"tcp://127.0.0.1:{quiet_site.port}"
    common = config(values=(28.0, 28.5), transient="auto", max_transient_periods=80)
    del common["transient_periods"]
    remote = SweepConfig(**common, backend_options={"actuator": "ideal", "rig": rig})
    local = SweepConfig(**common, backend_options=QUIET_LOOP)
    a, b = run_sweep(remote, watch=SILENT), run_sweep(local)
    assert a[[*COMPARED, "settled", "transient_periods_used"]].equals(
        b[[*COMPARED, "settled", "transient_periods_used"]]
    )
    assert a["transient_periods_used"].min() < 80  # a point settled before the cap


def test_a_realtime_site_paces_the_continuous_test(tmp_path):
    """Against ``pendsweep site --realtime`` the test runs at the wall clock's pace; rows count late replies."""
    site = SiteProcess("--once", "--realtime", *QUIET_SITE, "-o", str(tmp_path / "site-log.parquet"))
    rig = f"tcp://127.0.0.1:{site.port}"
    paced = SweepConfig(**config(values=(16.0, 17.0), transient_periods=3, record_periods=2,
                                 backend_options={"actuator": "ideal", "rig": rig}))  # fmt: skip
    start = time.perf_counter()
    rows = run_sweep(paced, watch=SILENT)
    wall = time.perf_counter() - start
    status, err = site.finish()
    assert status == 0, err
    test_time = 2 * 5 / 2.5  # two points of 5 forcing periods at 2.5 Hz [s]
    assert wall >= 0.95 * test_time
    # how many replies came late depends on the machine's load (a benchmark's business); each point counts its own
    assert rows["late_ticks"].between(0, 5 * 400).all()
    log = pq.read_table(tmp_path / "site-log.parquet", columns=["late"]).to_pandas()
    assert len(log) >= 2 * 5 * 400 and "deadline misses" in err  # the points, then the final ramp down


def test_the_operators_nudge_takes_a_resting_pendulum_off_the_semi_trivial_branch(tmp_path):
    """A pendulum at rest stays at rest past the boundary (vertical pivot, Coulomb friction); where an in-process
    sweep would kick, the test asks for a nudge, and a site takes the operator's SIGUSR1 as 0.1 rad."""
    site = SiteProcess("--once", "--theta0", "0", *QUIET_SITE)
    out = tmp_path / "rig.parquet"
    client = run_cli(out, f"tcp://127.0.0.1:{site.port}", "--transient-periods", "40",
                     values=("--from", "24", "--to", "25", "--step", "1"))  # fmt: skip
    asked = 0
    for line in client.stderr:
        if "nudge it" in line:
            asked += 1
            os.kill(site.proc.pid, signal.SIGUSR1)
    assert client.wait(timeout=120) == 0
    status, err = site.finish()
    assert status == 0 and "nudged by 0.1 rad" in err
    assert asked == 1  # before the second point only: the first started at rest from the site's own state
    swing = pq.read_table(out).to_pandas().groupby("alpha")["theta_absmax"].max()
    assert swing[24.0] == 0.0 and swing[25.0] > 0.1
