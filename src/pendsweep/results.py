"""Crash-safe, resumable, single-writer parquet results.

One process at a time writes an output: :class:`OutputLock` (``<output>.lock``,
owner pid and host inside) is taken before any work, and a second process is
refused at once. A run writes its finished units into ``<output>.parts/`` as
small parquet files (one row group per unit), each written to a temporary
name, fsynced and atomically renamed, so a killed process leaves only whole
parts behind; the run's
configuration is stored once in ``<output>.parts/config.json`` and every part
carries its hash. Rerunning the same configuration checks every part's hash,
skips the units they hold and goes on; when every unit is done the parts are
merged into ``<output>`` (again by atomic rename) and the folder is removed.
The merge streams one row group at a time (:mod:`pendsweep.merge`), so
neither the run nor its merge holds all rows: memory stays within the
store's buffer (at most ``flush_points`` units) and the row-key columns.
The final file carries the fully resolved configuration as JSON in its
parquet key-value metadata under ``pendsweep``.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import logging
import os
import shutil
import socket
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyarrow as pa
import pyarrow.parquet as pq

from .columns import has_duplicate_rows, read_parquet, sort_rows
from .errors import ResultsError
from .merge import plan_row_groups, unified_schema, write_row_groups

if TYPE_CHECKING:  # rows are pyarrow Tables here; frames only where they are asked for
    import pandas as pd

METADATA_KEY = b"pendsweep"
#: The run's metadata inside ``<output>.parts/`` (written once; parts carry only its hash).
CONFIG_FILE = "config.json"

_log = logging.getLogger("pendsweep")


class OutputLocked(ResultsError):
    """Another process is writing the same output (the message names it; exit status 2)."""


# Read once at import: os.umask can only be read by setting it, which is not thread-safe.
_UMASK = os.umask(0o022)
os.umask(_UMASK)


def config_hash(config: dict[str, Any]) -> str:
    """Stable hash of a JSON-able configuration (identifies resumable runs)."""
    text = json.dumps(config, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def run_metadata(kind: str, config: dict[str, Any], **extra: Any) -> dict[str, Any]:
    """Provenance stored with a result file: kind, resolved config, its hash, version, time."""
    from ._version import __version__

    return {
        "kind": kind,
        "config": config,
        "config_hash": config_hash(config),
        "package_version": __version__,
        **extra,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def check_writable(path: Path) -> None:
    """Raise :class:`ResultsError` unless a file can be created at ``path``."""
    path = Path(path)
    if path.exists() and path.is_dir():
        raise ResultsError(f"results path {str(path)!r} is a directory; give a file name ending in .parquet")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".write-test-")
        os.close(fd)
        os.unlink(tmp)
    except OSError as exc:
        raise ResultsError(f"cannot write results to {str(path)!r}: {exc.strerror or exc}") from None


def _atomic_write(path: Path, write: Callable[[Any], None]) -> None:
    """Create ``path`` with ``write(file)`` so that readers see all of it or nothing."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        # mkstemp creates 0600 files; results get the permissions of any normal file.
        os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def atomic_write_table(table: pa.Table, path: Path) -> None:
    """Write ``table`` to ``path`` as parquet so that readers see all of it or nothing."""
    _atomic_write(path, lambda fh: pq.write_table(table, fh))


def as_table(rows: pa.Table | pd.DataFrame) -> pa.Table:
    """Rows as a pyarrow Table (a DataFrame is converted, its index dropped)."""
    if isinstance(rows, pa.Table):
        return rows
    return pa.Table.from_pandas(rows, preserve_index=False).replace_schema_metadata(None)


def concat_rows(tables: list[pa.Table]) -> pa.Table:
    """Tables concatenated; types unified (all-null or string columns from pandas frames) (empty: no columns)."""
    tables = [t for t in tables if t.num_columns]
    return pa.concat_tables(tables, promote_options="permissive") if tables else pa.table({})


def schema_with_metadata(schema: pa.Schema, metadata: dict[str, Any]) -> pa.Schema:
    """``schema`` carrying ``metadata`` as JSON under :data:`METADATA_KEY` (other keys kept)."""
    meta = dict(schema.metadata or {})
    meta[METADATA_KEY] = json.dumps(metadata, sort_keys=True).encode()
    return schema.with_metadata(meta)


def with_metadata(rows: pa.Table | pd.DataFrame, metadata: dict[str, Any]) -> pa.Table:
    table = as_table(rows)
    return table.replace_schema_metadata(schema_with_metadata(table.schema, metadata).metadata)


def read_metadata(path: Path) -> dict[str, Any]:
    """The ``pendsweep`` metadata of a parquet file written by this package."""
    try:
        meta = pq.read_schema(path).metadata or {}
    except (OSError, pa.ArrowInvalid) as exc:
        raise ResultsError(f"cannot read {str(path)!r} as parquet: {exc}") from None
    if METADATA_KEY not in meta:
        raise ResultsError(f"{str(path)!r} carries no pendsweep metadata")
    return json.loads(meta[METADATA_KEY])


def read_results(path: Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read a results file and its metadata."""
    path = Path(path)
    if not path.is_file():
        raise ResultsError(f"no results file at {str(path)!r}")
    meta = read_metadata(path)
    return pq.read_table(path).to_pandas(), meta


def _part_metadata(part: pq.ParquetFile) -> dict[str, Any]:
    """A part's ``pendsweep`` metadata (``KeyError``, ``TypeError`` or ``ValueError`` when it has none that fits)."""
    meta = json.loads(part.schema_arrow.metadata[METADATA_KEY])
    if not isinstance(meta["final_states"], dict):
        raise ValueError("final_states is not a mapping")
    return meta


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
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666 & ~_UMASK)
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


class ResultStore:
    """Buffered, crash-safe, single-writer store for one run's results.

    Layout while a run is unfinished: ``<output>.lock`` (:class:`OutputLock`),
    ``<output>.parts/config.json`` (the run's metadata, written once) and
    ``<output>.parts/part-NNNNNN-PID.parquet`` files, each holding one row
    group per unit and carrying only the configuration hash, the final states
    of its units and the unit of each row group (``row_group_units``). When
    every unit is done, :meth:`finalize` merges the parts into ``<output>``
    (metadata and all final states included) and removes the folder; a run that finds a
    finished ``<output>`` of its configuration removes any folder left by a
    kill after the final rename.

    Parameters
    ----------
    path : Path
        Final parquet file.
    metadata : dict
        Resolved configuration and provenance; ``metadata["config_hash"]``
        identifies runs that may resume each other.
    row_columns : sequence of str
        Columns that identify one row (e.g. ``direction, point, start,
        period``); duplicates left by a crash are dropped on them and the
        final file is sorted by them.
    overwrite : bool
        Discard any previous file or parts at ``path``.
    flush_points, flush_seconds : int, float
        Persist the buffer once it holds this many units, and at the latest
        ``flush_seconds`` after the last write: a timer writes a finished unit
        even while the next one is still running (each part costs two fsyncs,
        so a fast sweep writes about one a second).

    Raises
    ------
    OutputLocked
        Another process is writing ``path``.
    ResultsError
        ``path`` is not writable, or holds (or its parts hold) results of a
        different configuration.
    """

    def __init__(
        self,
        path: Path,
        metadata: dict[str, Any],
        row_columns: Iterable[str],
        overwrite: bool = False,
        flush_points: int = 1024,
        flush_seconds: float = 1.0,
    ) -> None:
        self.path = Path(path)
        self.metadata = metadata
        self.config_hash = metadata["config_hash"]
        self.row_columns = list(row_columns)
        self.parts = self.path.with_name(self.path.name + ".parts")
        self.flush_points = flush_points
        self.flush_seconds = flush_seconds
        self._buffer: list[tuple[str, pa.Table]] = []  # (unit key, its rows), in the order they finished
        self._buffer_states: dict[str, list[float]] = {}
        self._last_flush = time.monotonic()
        # The scan adds units from its own thread; the timer writes from another.
        self._mutex = threading.Lock()
        self._timer: threading.Timer | None = None
        self._timer_error: BaseException | None = None
        self._closed = False
        self._part_counter = 0  # index of the next part; 0 while no part is on disk
        check_writable(self.path)
        self.lock = OutputLock(self.path)
        try:
            if overwrite:
                shutil.rmtree(self.parts, ignore_errors=True)
                if self.path.exists():
                    self.path.unlink()
            self._open()
        except BaseException:
            self.lock.release()
            raise

    def _open(self) -> None:
        if self.path.exists():
            self._check_hash(read_metadata(self.path).get("config_hash"), self.path)
            shutil.rmtree(self.parts, ignore_errors=True)  # left by a kill after the final rename
            return
        config_file = self.parts / CONFIG_FILE
        if config_file.exists():
            try:
                stored = json.loads(config_file.read_text())
            except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
                _log.warning(
                    f"{str(config_file)!r} is unreadable ({exc}); rewriting it (every part is checked on its own)"
                )
            else:
                self._check_hash(stored.get("config_hash") if isinstance(stored, dict) else None, config_file)
                if isinstance(stored.get("created"), str):  # a resumed run keeps the time it was first started
                    self.metadata = dict(self.metadata, created=stored["created"])
        self.parts.mkdir(exist_ok=True)
        text = json.dumps(self.metadata, sort_keys=True).encode()
        _atomic_write(config_file, lambda fh: fh.write(text))
        indices = [int(f.name.split("-")[1]) for f in self.parts.glob("part-*.parquet")]
        self._part_counter = max(indices, default=-1) + 1

    def _check_hash(self, have: Any, where: Path) -> None:
        if have != self.config_hash:
            raise ResultsError(
                f"{str(where)!r} holds results of a different configuration; "
                "pass --overwrite to replace them or choose another output path"
            )

    @property
    def complete(self) -> bool:
        """True when the final file exists (a previous run finished)."""
        return self.path.exists()

    # -- resume ---------------------------------------------------------------
    def done(self, columns: list[str] | None = None) -> tuple[pa.Table, dict[str, list[float]]]:
        """Rows and final states (per unit key) already persisted (empty on a fresh start).

        ``columns`` projects the rows: None reads every column; a list reads
        those and the row columns (by which duplicates are dropped); an
        empty list reads no rows at all, only the states, so a resumed run
        of a million rows need not hold them.

        Every part's configuration hash is checked (a mismatch is an error).
        A part that cannot be read is reported on the ``pendsweep`` logger,
        moved aside (``*.corrupt``) and its units count as not done, so the
        run recomputes them.
        """
        projection = None if columns is None else self.row_columns + [c for c in columns if c not in self.row_columns]
        if self.path.exists():
            states = read_metadata(self.path).get("final_states", {})
            if columns == []:
                return pa.table({}), states
            with pq.ParquetFile(self.path) as final:
                return final.read(columns=projection), states
        tables, states = [], {}
        for f in sorted(self.parts.glob("part-*.parquet")):
            try:
                with pq.ParquetFile(f) as part:
                    meta = _part_metadata(part)
                    table = part.read(columns=projection) if columns != [] else None
            except (OSError, ValueError, KeyError, TypeError, pa.ArrowException) as exc:
                self._set_aside(f, exc)
                continue
            self._check_hash(meta.get("config_hash"), f)
            if table is not None:
                tables.append(table.replace_schema_metadata(None))
            states.update(meta["final_states"])
        return self._unique(concat_rows(tables)), states

    def _set_aside(self, part: Path, error: BaseException) -> None:
        _log.warning(f"part {str(part)!r} is unreadable ({error}); its units will be recomputed")
        os.replace(part, part.with_name(part.name + ".corrupt"))

    def _unique(self, table: pa.Table) -> pa.Table:
        """One copy of each row key: a part repeats a unit only if a crash hit between two renames."""
        if not has_duplicate_rows(table, self.row_columns):
            return table
        df = table.to_pandas().drop_duplicates(subset=self.row_columns, keep="last")
        return pa.Table.from_pandas(df, schema=table.schema, preserve_index=False)

    # -- writing --------------------------------------------------------------
    def add(self, rows: pa.Table | pd.DataFrame, key: str, final_state: list[float]) -> None:
        """Buffer one finished unit of work; persist it now or by ``flush_seconds`` after the last write."""
        table = as_table(rows)
        with self._mutex:
            self._raise_timer_error()
            self._buffer.append((key, table))
            self._buffer_states[key] = final_state
            wait = self.flush_seconds - (time.monotonic() - self._last_flush)
            if len(self._buffer) >= self.flush_points or wait <= 0:
                self._write_buffer()
            elif self._timer is None:
                self._timer = threading.Timer(wait, self._timed_flush)
                self._timer.daemon = True
                self._timer.start()

    def flush(self) -> None:
        """Persist the buffered units now."""
        with self._mutex:
            self._raise_timer_error()
            self._write_buffer()

    def _timed_flush(self) -> None:
        with self._mutex:
            self._timer = None
            if self._closed:
                return
            try:
                self._write_buffer()
            except BaseException as exc:  # kept for the scan's thread: a timer's traceback would be lost
                self._timer_error = exc

    def _raise_timer_error(self) -> None:
        if self._timer_error is not None:
            exc, self._timer_error = self._timer_error, None
            raise exc

    def _cancel_timer(self) -> None:
        """Stop a pending timed write (the caller holds the mutex)."""
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _write_buffer(self) -> None:
        """Write the buffer as one part (the caller holds the mutex)."""
        self._cancel_timer()
        if not self._buffer:
            return
        # Units with rows, each its own row group, so the final merge can move whole units.
        units = [(key, rows.num_rows) for key, rows in self._buffer if rows.num_rows]
        meta = {
            "config_hash": self.config_hash,
            "final_states": self._buffer_states,
            "row_group_units": [key for key, _ in units],
        }
        table = with_metadata(concat_rows([rows for _, rows in self._buffer]), meta)

        def write(sink) -> None:
            with pq.ParquetWriter(sink, table.schema) as writer:
                offset = 0
                for _, n_rows in units:
                    writer.write_table(table.slice(offset, n_rows), row_group_size=n_rows)
                    offset += n_rows

        part = self.parts / f"part-{self._part_counter:06d}-{os.getpid()}.parquet"
        _atomic_write(part, write)
        self._part_counter += 1
        self._buffer, self._buffer_states = [], {}
        self._last_flush = time.monotonic()

    def finalize(self, return_rows: bool = True) -> pa.Table | None:
        """Merge parts into the final file atomically, remove the parts and release the lock.

        Returns the rows, sorted by the row columns (None when not
        ``return_rows``). A run whose every unit is still in the buffer (no
        part on disk: it finished within one checkpoint interval of a fresh
        start) writes the final file straight from memory instead of through
        a part it would read back. Otherwise the parts are streamed into the
        final file one row group at a time (:meth:`_merge_parts`) and the rows
        asked for are read back from it.
        """
        with self._mutex:
            in_memory = self._part_counter == 0
            if in_memory:
                self._cancel_timer()
                table = self._unique(concat_rows([rows for _, rows in self._buffer]))
                states = self._buffer_states
                self._buffer, self._buffer_states = [], {}
        if in_memory:
            table = sort_rows(table, self.row_columns)
            atomic_write_table(with_metadata(table, self._final_metadata(states)), self.path)
        else:
            self.flush()
            self._merge_parts()
        shutil.rmtree(self.parts, ignore_errors=True)
        self.close()
        if not return_rows:
            return None
        return table if in_memory else read_parquet(self.path).replace_schema_metadata(None)

    def _final_metadata(self, states: dict[str, list[float]]) -> dict[str, Any]:
        return dict(self.metadata, final_states=states, completed=time.strftime("%Y-%m-%dT%H:%M:%S%z"))

    def _merge_parts(self) -> None:
        """Write the final file from the parts: streamed by row group, or merged in memory when it must be.

        The stream (:func:`pendsweep.merge.plan_row_groups`) holds the row-key
        columns of all parts and one row group; its file has the rows, order,
        schema and metadata of the in-memory merge (read back, the two are
        equal). When the row groups' key ranges overlap (or a part from an
        older version does not name its row groups' units) every row is read,
        duplicates dropped, sorted and written from memory instead.
        """
        parts, units, states = [], [], {}
        try:
            for f in sorted(self.parts.glob("part-*.parquet")):
                try:
                    part = pq.ParquetFile(f, pre_buffer=False)  # pre-buffering keeps every row group read
                    meta = _part_metadata(part)
                except (OSError, ValueError, KeyError, TypeError, pa.ArrowException) as exc:
                    self._set_aside(f, exc)
                    continue
                self._check_hash(meta.get("config_hash"), f)
                parts.append(part)
                units.append(meta.get("row_group_units"))
                states.update(meta["final_states"])
            metadata = self._final_metadata(states)
            plan = plan_row_groups(parts, units, self.row_columns) if parts else None
            if plan is None:
                table = self._unique(concat_rows([part.read().replace_schema_metadata(None) for part in parts]))
                atomic_write_table(with_metadata(sort_rows(table, self.row_columns), metadata), self.path)
            else:
                schema = schema_with_metadata(unified_schema(parts), metadata)
                _atomic_write(self.path, lambda sink: write_row_groups(sink, parts, plan, schema))
        finally:
            for part in parts:
                part.close()

    def close(self) -> None:
        """Release the lock (idempotent). Unflushed units are dropped; parts stay for a later resume."""
        with self._mutex:
            self._closed = True
            self._cancel_timer()
        self.lock.release()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
