"""A site that its clients can wait for (issue 31): a client started with its site, `pendsweep wait`, the README.

`pendsweep site` listens only after loading its compiled kernels (about 2 s),
so the documented lines, pasted as one block, start the client first. The
remote-rig client retries a refused connection for a bounded time, `pendsweep
wait` does it for OpenSees (which connects once), and the probe that `wait`
makes is no session of the site. Everything on 127.0.0.1.
"""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pyarrow.parquet as pq
from click.testing import CliRunner

from pendsweep import FIG9_PO, make_backend
from pendsweep.cli import main
from pendsweep.hybrid import connect
from pendsweep.hybrid.log import SiteLog
from pendsweep.hybrid.rig import rig_from_options
from pendsweep.hybrid.server import SiteServer
from pendsweep.model.params import ModelParams
from site_helpers import RawClient

README = Path(__file__).resolve().parents[1] / "README.md"
DT = 1e-3


def free_port() -> int:
    """A loopback port nobody listens on (bound and released at once)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_site(port: int, log_path: Path | None = None) -> tuple[SiteServer, threading.Thread, dict]:
    """A ``--once`` site on ``port`` served from a thread; the dict gets its exit status under ``"status"``."""
    rig, config = rig_from_options({}, ModelParams.from_mapping({"fe": 2.2}))
    server = SiteServer(rig, SiteLog(log_path, config), port=port, once=True, timeout=5.0)
    outcome: dict = {}
    thread = threading.Thread(target=lambda: outcome.update(status=server.serve()), daemon=True)
    thread.start()
    return server, thread, outcome


def test_a_client_started_before_its_site_runs_when_the_site_comes_up():
    port = free_port()
    remote = make_backend("substructured", actuator="ideal", rig=f"tcp://127.0.0.1:{port}")
    runs: dict = {}

    def drive() -> None:
        runs["run"] = remote.run_point(FIG9_PO, remote.initial_state(FIG9_PO, 0, 0, 0.1, 0), 2, 2)

    client = threading.Thread(target=drive, daemon=True)
    client.start()
    time.sleep(1.0)  # the client has met a refused connection by now
    server, site, outcome = start_site(port)
    client.join(60)
    site.join(60)
    assert not client.is_alive() and not site.is_alive()
    assert runs["run"].status.value == "ok" and runs["run"].periods_done == 4
    assert outcome["status"] == 0 and len(server.sessions) == 1


def test_a_client_whose_site_never_comes_fails_in_one_line_after_the_deadline(tmp_path, monkeypatch):
    monkeypatch.setattr(connect, "CONNECT_DEADLINE", 0.5)
    started = time.monotonic()
    result = CliRunner().invoke(
        main,
        ["alpha", "--from", "4", "--to", "4", "--mode", "fresh", "--backend", "substructured",
         "-B", f"rig=tcp://127.0.0.1:{free_port()}", "-o", str(tmp_path / "x.parquet"), "--no-progress"],
    )  # fmt: skip
    assert result.exit_code == 1, result.output
    assert [line for line in result.output.splitlines() if line.startswith("Error")] == result.output.splitlines()
    assert "cannot reach the rig at tcp://127.0.0.1:" in result.output and "within 0.5 s" in result.output
    assert 0.5 <= time.monotonic() - started < 30


def test_wait_returns_once_the_site_listens_and_its_probe_is_no_session(tmp_path):
    port = free_port()
    log = tmp_path / "log.parquet"
    waiting = subprocess.Popen(
        [sys.executable, "-m", "pendsweep.cli", "wait", f"tcp://127.0.0.1:{port}", "--timeout", "60"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(0.5)
    server, site, outcome = start_site(port, log)
    _, err = waiting.communicate(timeout=60)
    assert waiting.returncode == 0, err
    client = RawClient(port)  # the --once site still serves, its first client being this one
    client.setup()
    for k in range(20):
        client.step(0.0, 0.0, (k + 1) * DT)
    client.frame(99)
    site.join(30)
    client.close()
    assert outcome["status"] == 0 and len(server.sessions) == 1 and server.sessions[0].ok
    table = pq.read_table(log)
    meta = json.loads(table.schema.metadata[b"pendsweep"])
    assert table.num_rows == 20 and set(table["session"].to_pylist()) == {0}
    assert [s["ended"] for s in meta["sessions"]] == ["die"]


def test_wait_for_a_site_that_never_comes_gives_up_in_one_line():
    started = time.monotonic()
    result = CliRunner().invoke(main, ["wait", f"tcp://127.0.0.1:{free_port()}", "--timeout", "0.3"])
    assert result.exit_code == 1, result.output
    assert result.output.count("\n") == 1 and "cannot reach a site at tcp://127.0.0.1:" in result.output
    assert "within 0.3 s" in result.output and 0.3 <= time.monotonic() - started < 5


def test_the_readme_hybrid_lines_pasted_as_one_block_run(tmp_path):
    """The README's site, client and sync lines, run by bash in one go (the client's run cut to 4 periods)."""
    lines = README.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("pendsweep site "))
    last = next(i for i in range(first, len(lines)) if "pendsweep sync" in lines[i])
    port = str(free_port())
    block = []
    for line in lines[first : last + 1]:
        command = line.split("#")[0].strip().replace("8090", port)
        if "rig=tcp://" in command:
            command += " --transient-periods 2 --record-periods 2 --no-progress"
        block.append(command)
    assert "&" in block[0] and any(c.startswith("wait") for c in block), block
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    done = subprocess.run(
        ["bash", "-e", "-c", "\n".join(block)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert re.search(r"Table I ratio\s+\d", done.stdout), done.stdout
    assert "left after 1820 steps" in done.stderr and "could not connect" not in done.stderr
