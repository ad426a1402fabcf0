"""One writer per output: ``<output>.lock``, an advisory ``flock`` with its holder named inside.

A run takes the lock before any work (:class:`pendsweep.engine.results.ResultStore`
does); a second process writing the same output is refused at once, with
the holder's pid and host. The kernel releases the ``flock`` of a process
that dies however it dies, so a later run takes a stale lock over.
"""

from __future__ import annotations

import fcntl
import json
import logging
import os
import socket
import time
from pathlib import Path
from typing import Any

from ..errors import ResultsError

_log = logging.getLogger("pendsweep")


class OutputLocked(ResultsError):
    """Another process is writing the same output (the message names it; exit status 2)."""


# Read once at import: os.umask can only be read by setting it, which is not thread-safe.
UMASK = os.umask(0o022)
os.umask(UMASK)


class OutputLock:
    """Exclusive right to write one output, held from before any work until the run ends.

    The lock is ``<output>.lock``: an advisory ``flock`` on it (released by
    the kernel when its process dies, however it dies) plus the holder's
    pid, host and start time written inside, so a refusal can name the
    holder. A lock file whose flock is free is stale (its process died):
    the next run takes it over and says so.

    Raises
    ------
    OutputLocked
        When another process (or another store in this process) holds it.
    """

    def __init__(self, output: Path) -> None:
        self.path = Path(output).with_name(Path(output).name + ".lock")
        self._fd: int | None = None
        self.previous: dict[str, Any] | None = None  # the stale holder taken over, if any
        while self._fd is None:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666 & ~UMASK)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                held = True
            except OSError as exc:  # a filesystem without flock: judge by the pid written inside
                _log.warning(f"no file locking on {str(self.path.parent)!r} ({exc.strerror}); going by the pid inside")
                held = _alive_elsewhere(_read_holder(fd))
            else:
                held = False
            if held:
                holder = _read_holder(fd)
                os.close(fd)
                raise OutputLocked(
                    f"{str(output)!r} is being written by {_describe(holder)} (lock {str(self.path)!r}); "
                    "wait for it to finish or choose another output path"
                )
            # The holder may have released and removed the file between our open and flock:
            # only a lock on the file that is still at the path counts.
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            self.previous = _read_holder(fd)
            me = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(me).encode(), 0)
            os.fsync(fd)
            self._fd = fd
        if self.previous:
            _log.warning(f"took over the stale lock of {_describe(self.previous)} on {str(output)!r}")

    def release(self) -> None:
        """Remove the lock file and let go (idempotent)."""
        if self._fd is None:
            return
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
        os.close(self._fd)
        self._fd = None


def _read_holder(fd: int) -> dict[str, Any]:
    try:
        holder = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
    except (UnicodeDecodeError, json.JSONDecodeError):
        return {}
    return holder if isinstance(holder, dict) else {}


def _alive_elsewhere(holder: dict[str, Any]) -> bool:
    """Whether a lock's holder may still run: another live pid on this host, or any pid on another host."""
    pid = holder.get("pid")
    if not isinstance(pid, int) or pid == os.getpid():
        return False
    if holder.get("host") != socket.gethostname():
        return True  # cannot be checked from here
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _describe(holder: dict[str, Any]) -> str:
    if not holder:
        return "another process"
    return f"pid {holder.get('pid', '?')} on host {holder.get('host', '?')} (since {holder.get('started', '?')})"
