"""The paper's experiment through a site: Fig. 11(a) swept in one continuous test, against the protocol's limit.

Ratios in one run (loopback round trips differ about 4x between machines, so
no absolute time is a goal):

* ``pendsweep alpha`` in continue mode with ``-B rig=`` against ``pendsweep
  site`` (the Table IV rig: servo actuator, noisy sensors), writing its
  results and its time series as a user's run does;
* the same client against a *null site* (:class:`NullSite`): the protocol
  answered at once with a constant reading, no physics, the limit of the
  protocol and of the client's own loop on this machine (goal: the real
  site within 1.5x of it);
* the in-process substructured continue sweep of the same values, beside them;
* the resume cost: a client killed after its second point and run again
  repeats at most one point's work (counted in controller ticks from the
  time series).

The full run is the paper's Fig. 11(a): 0-45 N in 0.5 N steps, 100 + 20
periods at 2.5 Hz, about 73 minutes of test time; ``--quick`` runs every
5 N with 10 + 5 periods.
"""

from __future__ import annotations

import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from .registry import benchmark
from .site import start_site

#: The rig of the Table IV test, served by the site (its sensors noisy, as a lab's).
SITE_ARGS = ("--set", "fe=2.5", "-B", "actuator=servo")


class NullSite:
    """A site that answers OpenFresco's protocol at once without physics: every reading is the same constant.

    It reads the client's set-up (11 int32), then frames of ``data_size``
    doubles, and answers each getDaqResponse (action 6) with one frame; die
    (99) ends it. Only for timing on loopback.
    """

    def __init__(self) -> None:
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conn, _ = self.listener.accept()
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        setup = self._read(conn, 44)
        size = int(np.frombuffer(setup, "<i4")[10])
        reply = np.zeros(size).tobytes()
        frame = bytearray(8 * size)
        view = memoryview(frame)
        while True:
            got = 0
            while got < len(frame):
                n = conn.recv_into(view[got:])
                if not n:
                    return
                got += n
            action = int(np.frombuffer(frame, "<f8", count=1)[0])
            if action == 99:
                return
            if action == 6:
                conn.sendall(reply)

    @staticmethod
    def _read(conn: socket.socket, n: int) -> bytes:
        data = b""
        while len(data) < n:
            chunk = conn.recv(n - len(data))
            if not chunk:
                raise ConnectionError("the client left during set-up")
            data += chunk
        return data

    def close(self) -> None:
        self.thread.join(timeout=30)
        self.listener.close()


def _config(values, transient: int, record: int, options: dict):
    from ..studies.sweep import SweepConfig

    return SweepConfig("alpha", tuple(values), {"fe": 2.5}, transient_periods=transient, record_periods=record,
                       kick=0.0, backend="substructured", backend_options=options)  # fmt: skip


def _client_run(values, transient: int, record: int, port: int, out: Path, **options) -> tuple[float, object]:
    """The user's command as an API call: a continuous test writing its results and time series; (wall, rows)."""
    from ..studies.rig_sweep import RigWatch
    from ..studies.sweep import run_sweep

    config = _config(values, transient, record, {"rig": f"tcp://127.0.0.1:{port}", **options})
    start = time.perf_counter()
    rows = run_sweep(config, out, overwrite=True, watch=RigWatch(reference=False, echo=lambda line: None))
    return time.perf_counter() - start, rows


def _resume_cost(tmp: Path) -> dict:
    """Kill a client after its second point, run it again; the steps the site served beyond the test's, in points."""
    values, transient, record = (16.0, 17.0, 18.0, 19.0), 10, 5
    out = tmp / "resume.parquet"
    proc, port = start_site(*SITE_ARGS, once=False)  # the killed client's session, then the resumed one
    base = [sys.executable, "-m", "pendsweep.cli", "alpha", "--from", "16", "--to", "19", "--step", "1", "--fe",
            "2.5", "--transient-periods", str(transient), "--record-periods", str(record), "--backend",
            "substructured", "-B", f"rig=tcp://127.0.0.1:{port}", "-o", str(out)]  # fmt: skip
    try:
        first = subprocess.Popen(base, stderr=subprocess.PIPE, text=True)
        points = 0
        for line in first.stderr:
            points += " theta_max " in line
            if points == 2:
                first.send_signal(signal.SIGKILL)
                break
        first.wait()
        subprocess.run(base, capture_output=True, check=True, timeout=600)
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=60)
    served = sum(int(n) for n in re.findall(r"left after (\d+) steps", err))
    import pyarrow.parquet as pq

    ramp = int((pq.read_table(tmp / "resume-timeseries.parquet", columns=["point"])["point"].to_numpy() < 0).sum())
    per_point = (transient + record) * 400
    return {
        "points": len(values),
        "steps_served": served,
        "steps_of_the_final_ramp_down": ramp,
        "steps_needed": len(values) * per_point,
        "points_repeated": (served - ramp - len(values) * per_point) / per_point,
    }


@benchmark("rig_sweep")
def bench_rig_sweep(quick: bool) -> dict:
    from ..studies.sweep import run_sweep

    if quick:
        values, transient, record = np.arange(0.0, 45.01, 5.0), 10, 5
    else:
        values, transient, record = np.arange(0.0, 45.01, 0.5), 100, 20
    test_seconds = len(values) * (transient + record) / 2.5
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        proc, port = start_site(*SITE_ARGS)
        site_wall, rows = _client_run(values, transient, record, port, tmp / "site.parquet")
        proc.communicate(timeout=120)
        null = NullSite()
        # without the pendulum's force the numerical model swings past the stroke at 45 N: no limit here
        null_wall, _ = _client_run(values, transient, record, null.port, tmp / "null.parquet", stroke=1.0)
        null.close()
        start = time.perf_counter()
        run_sweep(_config(values, transient, record, {}), tmp / "local.parquet")  # the Table IV rig in process
        in_process = time.perf_counter() - start
        resume = _resume_cost(tmp)
    trips = rows.groupby("point")[["round_trip_p50", "round_trip_p99", "round_trip_max"]].first()
    return {
        "points": len(values),
        "periods_per_point": transient + record,
        "test_seconds": test_seconds,
        "site_wall_seconds": site_wall,
        "null_site_wall_seconds": null_wall,
        "site_over_null": site_wall / null_wall,
        "goal_site_over_null": 1.5,
        "times_real_time": test_seconds / site_wall,
        "round_trip_p50_us_median": float(trips["round_trip_p50"].median() * 1e6),
        "round_trip_p99_us_median": float(trips["round_trip_p99"].median() * 1e6),
        "round_trip_max_us": float(trips["round_trip_max"].max() * 1e6),
        "in_process_wall_seconds": in_process,
        "site_over_in_process": site_wall / in_process,
        "resume": resume,
        "goal_points_repeated": 1.0,
    }
