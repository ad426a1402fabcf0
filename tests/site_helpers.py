"""Helpers of the site tests: a raw protocol client, an in-process site and a site subprocess."""

from __future__ import annotations

import re
import socket
import struct
import subprocess
import sys
import threading
import time
import weakref
from pathlib import Path

import numpy as np

from pendsweep.hybrid.access import LOOPBACK_NETWORKS, parse_allow
from pendsweep.hybrid.log import SiteLog
from pendsweep.hybrid.rig import rig_from_options
from pendsweep.hybrid.server import SiteServer
from pendsweep.model.params import ModelParams

OPENSEES_SETUP = (1, 1, 1, 0, 1, 0, 0, 0, 1, 0, 256)


class RawClient:
    """A protocol client that sends whatever it is told (the tests' adversary).

    ``source`` binds the client's own address first (another loopback address,
    127.0.0.2 and the like, plays a host on the lab network).
    """

    def __init__(self, port: int, host: str = "127.0.0.1", source: str | None = None) -> None:
        self.sock = socket.create_connection((host, port), timeout=5, source_address=(source, 0) if source else None)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.data_size = 0

    def setup(self, sizes=OPENSEES_SETUP) -> None:
        self.data_size = sizes[10]
        self.send(struct.pack("<11i", *sizes))

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def frame(self, action: float, *values: float) -> None:
        f = np.zeros(self.data_size)
        f[0] = action
        f[1 : 1 + len(values)] = values
        self.send(f.astype("<f8").tobytes())

    def reply(self) -> np.ndarray:
        want = 8 * self.data_size
        buf = b""
        while len(buf) < want:
            chunk = self.sock.recv(want - len(buf))
            if not chunk:
                raise ConnectionError("site closed the connection")
            buf += chunk
        return np.frombuffer(buf, "<f8")

    def step(self, d: float, v: float, t: float) -> float:
        """One OpenSees-like step: trial, getForce, commit; returns the force."""
        self.frame(3, d, v, 0.0, t)
        self.frame(10)
        force = float(self.reply()[0])
        self.frame(5)
        return force

    def close(self) -> None:
        self.sock.close()


class ThreadSite:
    """A ``--once`` site served from a thread of this process, with a short timeout (``allow``: as ``--allow``)."""

    def __init__(
        self,
        options: dict | None = None,
        timeout: float = 1.0,
        log_path: Path | None = None,
        allow: tuple[str, ...] = (),
        **sets,
    ):
        params = ModelParams.from_mapping(sets)
        self.rig, config = rig_from_options(dict(options or {}), params)
        self.log = SiteLog(log_path, config)
        allowed = parse_allow(allow) if allow else LOOPBACK_NETWORKS
        self.server = SiteServer(self.rig, self.log, allow=allowed, port=0, once=True, timeout=timeout)
        self.port = self.server.address[1]
        self.status: int | None = None
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        self.status = self.server.serve()

    def join(self, limit: float = 20.0) -> int:
        self.thread.join(limit)
        assert not self.thread.is_alive(), "the site hung"
        return self.status

    @property
    def reason(self) -> str:
        return self.server.sessions[-1].reason


def _kill(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
        proc.wait()


class SiteProcess:
    """``pendsweep site --port 0 ...`` as a subprocess; ``port`` parsed from its listening line."""

    def __init__(self, *args: str, start_timeout: float = 120.0) -> None:
        cmd = [sys.executable, "-m", "pendsweep.cli", "site", "--port", "0", *args]
        self.proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        weakref.finalize(self, _kill, self.proc)  # a failed test never leaves a site listening
        self.lines: list[str] = []
        deadline = time.monotonic() + start_timeout
        while time.monotonic() < deadline:
            line = self.proc.stderr.readline()
            if not line:
                break
            self.lines.append(line)
            found = re.search(r"listening on [\d.]+:(\d+)", line)
            if found:
                self.port = int(found.group(1))
                return
        self.proc.kill()
        raise RuntimeError(f"site did not start: {''.join(self.lines)}")

    def finish(self, timeout: float = 60.0) -> tuple[int, str]:
        """Wait for exit; (status, the rest of stderr)."""
        _, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, "".join(self.lines) + err

    def stop(self) -> tuple[int, str]:
        self.proc.terminate()
        return self.finish()
