"""Crash-safe, resumable parquet results.

A run writes its finished points into ``<output>.parts/`` as small parquet
files, each written to a temporary name, fsynced and atomically renamed, so a
killed process leaves only whole parts behind. Rerunning the same
configuration reads the parts, skips the points they hold and goes on; when
every point is done the parts are merged into ``<output>`` (again by atomic
rename) and the folder is removed. Every file carries the fully resolved
configuration as JSON in its parquet key-value metadata under ``pendsweep``.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, Iterable

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from .errors import ResultsError

METADATA_KEY = b"pendsweep"

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


def atomic_write_table(table: pa.Table, path: Path) -> None:
    """Write ``table`` to ``path`` so that readers see all of it or nothing."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        # mkstemp creates 0600 files; results get the permissions of any normal file.
        os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, "wb") as fh:
            pq.write_table(table, fh)
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


def with_metadata(df: pd.DataFrame, metadata: dict[str, Any]) -> pa.Table:
    table = pa.Table.from_pandas(df, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    meta[METADATA_KEY] = json.dumps(metadata, sort_keys=True).encode()
    return table.replace_schema_metadata(meta)


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


class ResultStore:
    """Buffered, crash-safe writer for one run's results.

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
        Persist the buffer after this many units or seconds, whichever first.
    """

    def __init__(
        self,
        path: Path,
        metadata: dict[str, Any],
        row_columns: Iterable[str],
        overwrite: bool = False,
        flush_points: int = 16,
        flush_seconds: float = 1.0,
    ) -> None:
        self.path = Path(path)
        self.metadata = metadata
        self.row_columns = list(row_columns)
        self.parts = self.path.with_name(self.path.name + ".parts")
        self.flush_points = flush_points
        self.flush_seconds = flush_seconds
        self._buffer: list[pd.DataFrame] = []
        self._buffer_states: dict[str, list[float]] = {}
        self._last_flush = time.monotonic()
        check_writable(self.path)
        if overwrite:
            if self.parts.exists():
                shutil.rmtree(self.parts)
            if self.path.exists():
                self.path.unlink()
        self._check_compatible()
        self.parts.mkdir(exist_ok=True)
        self._part_counter = len(list(self.parts.glob("part-*.parquet")))

    # -- resume ---------------------------------------------------------------
    def _check_compatible(self) -> None:
        want = self.metadata["config_hash"]
        candidates = [self.path] if self.path.exists() else []
        candidates += sorted(self.parts.glob("part-*.parquet")) if self.parts.exists() else []
        for f in candidates[:1]:
            have = read_metadata(f).get("config_hash")
            if have != want:
                raise ResultsError(
                    f"{str(f)!r} holds results of a different configuration; "
                    "pass --overwrite to replace them or choose another output path"
                )

    @property
    def complete(self) -> bool:
        """True when the final file exists (a previous run finished)."""
        return self.path.exists()

    def done(self) -> tuple[pd.DataFrame, dict[str, list[float]]]:
        """Rows and final states already persisted (empty on a fresh start)."""
        if self.path.exists():
            df, meta = read_results(self.path)
            return df, meta.get("final_states", {})
        frames, states = [], {}
        for f in sorted(self.parts.glob("part-*.parquet")):
            frames.append(pq.read_table(f).to_pandas())
            states.update(read_metadata(f).get("final_states", {}))
        df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
        if not df.empty:
            # A part may repeat a unit only if a crash hit between two renames; keep one copy.
            df = df.drop_duplicates(subset=self.row_columns, keep="last")
        return df, states

    # -- writing --------------------------------------------------------------
    def add(self, rows: pd.DataFrame, key: str, final_state: list[float]) -> None:
        """Buffer one finished unit of work and persist when the buffer is due."""
        self._buffer.append(rows)
        self._buffer_states[key] = final_state
        due = time.monotonic() - self._last_flush >= self.flush_seconds
        if len(self._buffer) >= self.flush_points or due:
            self.flush()

    def flush(self) -> None:
        if not self._buffer:
            return
        df = pd.concat(self._buffer, ignore_index=True)
        meta = dict(self.metadata, final_states=self._buffer_states)
        part = self.parts / f"part-{self._part_counter:06d}-{os.getpid()}.parquet"
        atomic_write_table(with_metadata(df, meta), part)
        self._part_counter += 1
        self._buffer, self._buffer_states = [], {}
        self._last_flush = time.monotonic()

    def finalize(self) -> pd.DataFrame:
        """Merge parts into the final file atomically and remove the parts."""
        self.flush()
        df, states = self.done()
        df = df.sort_values(self.row_columns, kind="stable").reset_index(drop=True)
        meta = dict(self.metadata, final_states=states, completed=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        atomic_write_table(with_metadata(df, meta), self.path)
        shutil.rmtree(self.parts, ignore_errors=True)
        return df
