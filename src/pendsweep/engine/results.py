"""Crash-safe, resumable, single-writer parquet results.

One process at a time writes an output: :class:`OutputLock` (``<output>.lock``,
owner pid and host inside) is taken before any work, and a second process is
refused at once. A run buffers its finished units and writes them into
``<output>.parts/`` as parquet parts of many units each (one row group, up to
about :data:`pendsweep.engine.merge.ROW_GROUP_BYTES` or ``flush_points`` units), at
the latest ``flush_seconds`` after the oldest of them finished; each part is
written to a temporary name, fsynced and atomically renamed, so a killed
process leaves only whole parts behind. With the first part the run's
configuration is stored once in ``<output>.parts/config.json``, and every
part carries its hash. Rerunning the same configuration checks every part's
hash, skips the units they hold and goes on; when every unit is done the
parts and the units still buffered are merged into ``<output>`` (again by
atomic rename) and the folder is removed. A run that ends within one
checkpoint interval writes no part: its final file is its only write.
The merge streams a span of units at a time (:mod:`pendsweep.engine.merge`), so
neither the run nor its merge holds all rows: memory stays within the
store's buffer and the part it wrote last (a part's worth each), a row
group of a part and one of the final file, and the row-key columns.
The final file carries the fully resolved configuration as JSON in its
parquet key-value metadata under ``pendsweep``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import shutil
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyarrow as pa
import pyarrow.parquet as pq

from ..errors import ResultsError
from .columns import concat_rows, has_duplicate_rows, sort_rows
from .merge import (
    ROW_GROUP_BYTES,
    PartSource,
    TableSource,
    Units,
    plan_spans,
    row_bytes,
    unified_schema,
    units_table,
    write_options,
    write_spans,
)
from .output_lock import UMASK, OutputLock, OutputLocked  # noqa: F401 (OutputLocked: raised through here)

if TYPE_CHECKING:  # rows are pyarrow Tables here; frames only where they are asked for
    import pandas as pd

METADATA_KEY = b"pendsweep"
#: The run's metadata inside ``<output>.parts/`` (written once; parts carry only its hash).
CONFIG_FILE = "config.json"

_log = logging.getLogger("pendsweep")


def config_hash(config: dict[str, Any]) -> str:
    """Stable hash of a JSON-able configuration (identifies resumable runs)."""
    text = json.dumps(config, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def run_metadata(kind: str, config: dict[str, Any], **extra: Any) -> dict[str, Any]:
    """Provenance stored with a result file: kind, resolved config, its hash, version, time."""
    from .._version import __version__

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
        os.fchmod(fd, 0o666 & ~UMASK)
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


def atomic_write_table(table: pa.Table, path: Path, **options: Any) -> None:
    """Write ``table`` to ``path`` as parquet so that readers see all of it or nothing (``options``: the writer's)."""
    _atomic_write(path, lambda fh: pq.write_table(table, fh, **options))


def as_table(rows: pa.Table | pd.DataFrame) -> pa.Table:
    """Rows as a pyarrow Table (a DataFrame is converted, its index dropped)."""
    if isinstance(rows, pa.Table):
        return rows
    return pa.Table.from_pandas(rows, preserve_index=False).replace_schema_metadata(None)


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


class ResultStore:
    """Buffered, crash-safe, single-writer store for one run's results.

    Layout while a run is unfinished: ``<output>.lock`` (:class:`OutputLock`),
    ``<output>.parts/config.json`` (the run's metadata, written once) and
    ``<output>.parts/part-NNNNNN-PID.parquet`` files, each holding the rows of
    the units buffered since the previous part as one row group, and
    carrying only the configuration hash, the final states of its units and
    its units with their row counts in row order (``units``). When every
    unit is done, :meth:`finalize` merges the parts and the units still
    buffered into ``<output>`` (metadata and all final states included) and
    removes the folder; a run that finds a finished ``<output>`` of its
    configuration removes any folder left by a kill after the final rename.

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
    flush_points, flush_seconds, flush_bytes : int, float, int
        Write the buffer as a part once it holds ``flush_points`` units or
        about ``flush_bytes`` bytes of rows, and at the latest
        ``flush_seconds`` after the oldest unit in it was added (0: every
        unit at once): a writer thread writes it even while the next unit is
        still running. A unit waits at most ``flush_seconds`` in memory, and
        timed parts are at least that far apart (each costs two fsyncs).

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
        flush_bytes: int = ROW_GROUP_BYTES,
    ) -> None:
        self.path = Path(path)
        self.metadata = metadata
        self.config_hash = metadata["config_hash"]
        self.row_columns = list(row_columns)
        self.parts = self.path.with_name(self.path.name + ".parts")
        self.flush_points = flush_points
        self.flush_seconds = flush_seconds
        self.flush_bytes = flush_bytes
        self._buffer: list[tuple[str, pa.Table]] = []  # (unit key, its rows), in the order they finished
        self._buffer_states: dict[str, list[float]] = {}
        self._buffer_rows = 0
        self._flush_rows: int | None = None  # rows of about flush_bytes, from the first unit's row size
        self._deadline = 0.0  # when the oldest buffered unit must be on disk (time.monotonic)
        # The mutex guards the buffer (the scan adds units from its thread); the write lock, taken first,
        # makes parts one at a time, outside the mutex, on the writer thread or wherever the buffer is full.
        self._mutex = threading.Lock()
        self._write_lock = threading.Lock()
        self._due = threading.Condition(self._mutex)  # wakes the writer: a first unit buffered, or the end
        self._writer: threading.Thread | None = None  # started when the first unit has to wait
        self._timer_error: BaseException | None = None
        self._closed = False
        self._part_counter = 0  # index of the next part
        self._config_stored = False  # whether <output>.parts/config.json holds this run's metadata
        # The part written last, kept (one part's rows at most) so that the merge need not read it back,
        # and the units of a part being written (path None: none), which the merge need not wait for.
        self._last_part: tuple[Path | None, TableSource | None, dict[str, list[float]]] = (None, None, {})
        self._writing: tuple[Path | None, list[tuple[str, pa.Table]], dict[str, list[float]]] = (None, [], {})
        #: What this store did, for tests and benchmarks: seconds it held up the scan's thread (adding units,
        #: parts written there, the final merge), CPU seconds of parts the writer thread wrote, parts and
        #: their rows (written by either), the final file's row groups and the parts' row groups the merge read.
        self.counts: dict[str, float] = dict.fromkeys(
            ("scan_thread_seconds", "timer_cpu_seconds", "parts", "part_rows", "final_row_groups", "merge_reads"), 0
        )
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
                self._config_stored = True
        indices = [int(f.name.split("-")[1]) for f in self.parts.glob("part-*.parquet")]
        self._part_counter = max(indices, default=-1) + 1

    def _store_config(self) -> None:
        """Write ``config.json`` before the first part (the caller holds the write lock).

        Not before: a run that ends within its first checkpoint interval
        writes no part, and so needs neither the folder nor the two fsyncs.
        """
        if self._config_stored:
            return
        self.parts.mkdir(exist_ok=True)
        text = json.dumps(self.metadata, sort_keys=True).encode()
        _atomic_write(self.parts / CONFIG_FILE, lambda fh: fh.write(text))
        self._config_stored = True

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
        """Buffer one finished unit of work; persist it within ``flush_seconds`` (at once when the buffer is full)."""
        started = time.perf_counter()
        table = as_table(rows)
        with self._mutex:
            self._raise_timer_error()
            now = time.monotonic()
            first = not self._buffer
            if first:
                self._deadline = now + self.flush_seconds
            self._buffer.append((key, table))
            self._buffer_states[key] = final_state
            if table.num_rows:
                self._buffer_rows += table.num_rows
                if self._flush_rows is None:
                    self._flush_rows = max(1, int(self.flush_bytes / row_bytes(table)))
            full = len(self._buffer) >= self.flush_points or self._buffer_rows >= (self._flush_rows or math.inf)
            due = full or now >= self._deadline
            if not due and first:
                if self._writer is None or not self._writer.is_alive():  # (it ends after a failed write)
                    self._writer = threading.Thread(target=self._write_when_due, name="pendsweep-store", daemon=True)
                    self._writer.start()
                else:
                    self._due.notify()
        if due:
            self._write_buffer()
        self.counts["scan_thread_seconds"] += time.perf_counter() - started

    def flush(self) -> None:
        """Persist the buffered units now."""
        with self._mutex:
            self._raise_timer_error()
        self._write_buffer()

    def _write_when_due(self) -> None:
        """The writer thread: write the buffer when its oldest unit has waited ``flush_seconds``, until closed.

        One thread for the store's life (a thread a part cost 10 ms of
        start-up on a loaded machine). After a failed write it stops; the
        scan's thread raises the error at its next call.
        """
        while True:
            with self._mutex:
                while not self._closed and (not self._buffer or time.monotonic() < self._deadline):
                    self._due.wait(self._deadline - time.monotonic() if self._buffer else None)
                if self._closed:
                    return
            started = time.thread_time()
            try:
                self._write_buffer(timed=True)
            except BaseException as exc:  # kept for the scan's thread: this thread's traceback would be lost
                self._timer_error = exc
                return
            finally:
                self.counts["timer_cpu_seconds"] += time.thread_time() - started

    def _raise_timer_error(self) -> None:
        if self._timer_error is not None:
            exc, self._timer_error = self._timer_error, None
            raise exc

    def _write_buffer(self, timed: bool = False) -> None:
        """Write the buffer as one part of one row group.

        Parts are written one at a time (``_write_lock``), outside the
        mutex: the scan goes on adding units while the writer thread writes.
        A failed write puts its units back in front of the buffer.
        """
        with self._write_lock:
            with self._mutex:
                if timed and self._closed:
                    return
                if not self._buffer:
                    return
                taken = self._buffer, self._buffer_states, self._buffer_rows
                states = self._buffer_states
                part = self.parts / f"part-{self._part_counter:06d}-{os.getpid()}.parquet"
                self._part_counter += 1
                self._buffer, self._buffer_states, self._buffer_rows = [], {}, 0
                self._writing = (part, taken[0], states)
            try:
                rows, units = units_table(taken[0])  # outside the mutex: units go on being added
                table = with_metadata(rows, {"config_hash": self.config_hash, "final_states": states, "units": units})
                self._store_config()
                atomic_write_table(table, part, row_group_size=max(1, table.num_rows), **write_options(table.schema))
            except BaseException:
                with self._mutex:
                    self._writing = (None, [], {})
                    self._buffer = taken[0] + self._buffer
                    self._buffer_states = {**taken[1], **self._buffer_states}
                    self._buffer_rows += taken[2]
                raise
            with self._mutex:
                self._writing = (None, [], {})
                self._last_part = (part, TableSource(rows, units), states)
            self.counts["parts"] += 1
            self.counts["part_rows"] += table.num_rows

    def finalize(self, return_rows: bool = True) -> pa.Table | None:
        """Merge the parts and the buffered units into the final file atomically, remove the parts, release the lock.

        Returns the rows, sorted by the row columns (None when not
        ``return_rows``). The buffered units, the part written last and a
        part being written go into the final file from memory, not read back
        and not waited for: a run that finishes within one checkpoint
        interval of a fresh start costs one write, and one a little longer a
        part and the final file. Meanwhile the writer thread goes on, so a
        merge that outlasts the interval still has the buffer written as a
        part for a resume; a merge that fails writes them before the error
        goes on.
        """
        started = time.perf_counter()
        with self._mutex:  # one moment's view: the parts on disk, the one being written, the buffer
            self._raise_timer_error()
            buffer, states = list(self._buffer), dict(self._buffer_states)
            on_disk = sorted(self.parts.glob("part-*.parquet"))
            last_part, writing = self._last_part, self._writing
        in_memory = {}
        if last_part[0] is not None:
            in_memory[last_part[0]] = (last_part[1], last_part[2])
        if writing[0] is not None:  # its units as the writer thread took them, whether or not it has finished
            in_memory[writing[0]] = (TableSource(*units_table(writing[1])), writing[2])
        try:
            rows = self._merge(
                sorted(set(on_disk) | set(in_memory)), in_memory, units_table(buffer), states, return_rows
            )
        except BaseException:
            try:
                self.flush()
            except Exception as exc:  # the merge's error is the one to report
                _log.warning(f"could not write the last units of {str(self.path)!r} for a resume: {exc}")
            raise
        self._stop_writing()  # a part still being written is finished before its folder goes
        shutil.rmtree(self.parts, ignore_errors=True)
        self.close()
        self.counts["scan_thread_seconds"] += time.perf_counter() - started
        return rows

    def _final_metadata(self, states: dict[str, list[float]]) -> dict[str, Any]:
        return dict(self.metadata, final_states=states, completed=time.strftime("%Y-%m-%dT%H:%M:%S%z"))

    def _merge(
        self,
        paths: list[Path],
        in_memory: dict[Path, tuple[TableSource, dict[str, list[float]]]],
        buffered: tuple[pa.Table, Units],
        buffer_states: dict[str, list[float]],
        return_rows: bool,
    ) -> pa.Table | None:
        """Write the final file from the parts (``paths``, those in ``in_memory`` from there) and the buffer.

        Streamed by span, or merged in memory when it must be. The stream
        (:func:`pendsweep.engine.merge.plan_spans`) holds the row-key columns of
        all parts and about one row group; its file has the rows, order,
        schema and metadata of the in-memory merge (read back, the two are
        equal). When the units' key ranges overlap (or a part from an older
        version does not name its units) every row is read, duplicates
        dropped, sorted and written from memory instead.
        """
        files: list[pq.ParquetFile] = []
        sources: list[PartSource | TableSource] = []
        states: dict[str, list[float]] = {}
        try:
            for f in paths:
                if f in in_memory:  # written (or being written) by this store: its rows are here
                    sources.append(in_memory[f][0])
                    states.update(in_memory[f][1])
                    continue
                try:
                    part = pq.ParquetFile(f, pre_buffer=False)  # pre-buffering keeps every row group read
                    meta = _part_metadata(part)
                except (OSError, ValueError, KeyError, TypeError, pa.ArrowException) as exc:
                    self._set_aside(f, exc)
                    continue
                files.append(part)
                self._check_hash(meta.get("config_hash"), f)
                sources.append(PartSource(part, meta))
                states.update(meta["final_states"])
            buffer_rows, buffer_units = buffered
            if buffer_units:
                sources.append(TableSource(buffer_rows, buffer_units))
            states.update(buffer_states)
            metadata = self._final_metadata(states)
            plan = plan_spans(sources, self.row_columns)
            if plan is None:
                table = self._unique(concat_rows([source.read_all() for source in sources]))
                table = sort_rows(table, self.row_columns)
                atomic_write_table(with_metadata(table, metadata), self.path, **write_options(table.schema))
                self.counts["final_row_groups"] += 1  # at most a million rows (the writer's default) a group
                return table if return_rows else None
            keep: list[pa.Table] | None = [] if return_rows else None  # every row is asked for: none read back
            schema = schema_with_metadata(unified_schema(sources) if sources else pa.schema([]), metadata)

            def write(sink) -> None:
                groups, reads = write_spans(sink, sources, plan, schema, keep)
                self.counts["final_row_groups"] += groups
                self.counts["merge_reads"] += reads

            _atomic_write(self.path, write)
        finally:
            for part in files:
                part.close()
        if keep is None:
            return None
        return concat_rows(keep) if keep else pa.table({})

    def _stop_writing(self) -> None:
        """No part is written from now on (a timed write under way ends first); the writer thread ends."""
        with self._write_lock, self._mutex:
            self._closed = True
            self._last_part = (None, None, {})
            self._due.notify_all()

    def close(self) -> None:
        """Release the lock (idempotent). Unflushed units are dropped; parts stay for a later resume."""
        self._stop_writing()
        self.lock.release()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
