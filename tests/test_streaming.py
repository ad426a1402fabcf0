"""Results streamed to the resumable file: the final file as the in-memory merge's, resume, bounded memory."""

from __future__ import annotations

import functools
import json
import shutil
import threading
import time
import tracemalloc
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from pendsweep.engine.columns import table
from pendsweep.engine.executors import LocalExecutor
from pendsweep.engine.results import METADATA_KEY, ResultStore, read_metadata, run_metadata
from pendsweep.engine.scan import UnitResult, Work, run_scan
from pendsweep.studies.basins import BasinConfig, run_basins
from pendsweep.studies.hopf import HopfConfig, run_hopf
from pendsweep.studies.sweep import SweepConfig, run_sweep

#: Metadata that says when a file was made, not what it holds.
TIMES = ("created", "completed")


def _content(path: Path) -> tuple[pa.Table, dict[str, Any]]:
    """A final file's rows (one chunk per column) and its metadata without the times."""
    meta = {k: v for k, v in read_metadata(path).items() if k not in TIMES}
    rows = pq.ParquetFile(path).read()
    assert set(rows.schema.metadata) == {METADATA_KEY}
    return rows.replace_schema_metadata(None).combine_chunks(), meta


def _assert_same_file(streamed: Path, in_memory: Path) -> None:
    rows, meta = _content(streamed)
    reference_rows, reference_meta = _content(in_memory)
    assert rows.schema == reference_rows.schema
    assert rows.equals(reference_rows)
    assert meta == reference_meta


def _parts_of(path: Path) -> list[Path]:
    return sorted(path.with_name(path.name + ".parts").glob("part-*.parquet"))


RUNS = {
    "sweep": lambda out, seconds: run_sweep(
        SweepConfig("alpha", (10.0, 12.0, 14.0), mode="multistart", starts=3, transient_periods=20, record_periods=3),
        out,
        checkpoint_seconds=seconds,
    ),
    "basins": lambda out, seconds: run_basins(
        BasinConfig("alpha", (30.0, 31.0), {"fe": 2.5}, samples=48, max_periods=200),
        out,
        chunk_starts=16,
        checkpoint_seconds=seconds,
    ),
    "hopf": lambda out, seconds: run_hopf(
        HopfConfig(omega_hat=(0.95, 1.0, 1.05), masses=(5.9, 10.9), methods=("floquet",)),
        out,
        checkpoint_seconds=seconds,
    ),
}


@pytest.mark.parametrize("kind", sorted(RUNS))
def test_streamed_final_file_equals_the_in_memory_merge(tmp_path, kind, monkeypatch):
    """Every unit its own part (checkpoint 0 s): the parts are streamed. A long checkpoint keeps every
    unit in memory until the end, which writes the final file straight from there."""
    import pendsweep.engine.results as results

    streamed_plans = []
    plan = results.plan_spans
    monkeypatch.setattr(results, "plan_spans", lambda *a: streamed_plans.append(plan(*a)) or streamed_plans[-1])
    returned = RUNS[kind](tmp_path / "streamed.parquet", 0.0)
    assert streamed_plans and streamed_plans[0] is not None  # the stream ran, no fallback
    reference = RUNS[kind](tmp_path / "memory.parquet", 3600.0)
    _assert_same_file(tmp_path / "streamed.parquet", tmp_path / "memory.parquet")
    assert returned.equals(reference)
    assert not _parts_of(tmp_path / "streamed.parquet")


class _Interrupted(Exception):
    pass


class _StopsAfter:
    """Runs tasks in this thread and raises after ``units`` units, as a killed client would stop."""

    def __init__(self, units: int) -> None:
        self.units = units

    def map_unordered(self, tasks, n_jobs=1):
        for count, unit in enumerate(LocalExecutor().map_unordered(tasks, 1)):
            if count == self.units:
                raise _Interrupted
            yield unit

    def close(self) -> None:
        pass


def test_a_killed_basin_run_resumes_to_the_identical_file(tmp_path):
    """Killed after five of eight units (each written at once), with one part duplicated as a crash
    between two renames would leave it: the resumed file equals the uninterrupted one."""
    config = BasinConfig("alpha", (30.0, 31.0), {"fe": 2.5}, samples=64, max_periods=200)
    whole = tmp_path / "whole.parquet"
    run_basins(config, whole, chunk_starts=16, return_rows=False)
    out = tmp_path / "killed.parquet"
    with pytest.raises(_Interrupted):
        run_basins(config, out, chunk_starts=16, executor=_StopsAfter(5), checkpoint_seconds=0.0)
    parts = _parts_of(out)
    assert len(parts) == 5 and not out.exists()
    shutil.copy(parts[1], parts[-1].with_name("part-000099-1.parquet"))
    started = json.loads((out.with_name(out.name + ".parts") / "config.json").read_text())["created"]
    time.sleep(1.1)  # a resume a second later keeps the first start's time
    assert run_basins(config, out, chunk_starts=16, return_rows=False) is None
    _assert_same_file(out, whole)
    assert read_metadata(out)["created"] == started


@dataclass
class _WideScan:
    """A scan of cheap wide units (numbers, no integration): ``units`` x ``rows`` rows of ``columns`` floats."""

    units: int = 160
    rows: int = 1000
    columns: int = 40
    desc: str = "wide"
    row_columns: list[str] = field(default_factory=lambda: ["unit", "row"])
    resume_columns: list[str] = field(default_factory=list)

    def metadata(self) -> dict[str, Any]:
        return run_metadata("wide", {"units": self.units, "rows": self.rows, "columns": self.columns})

    def n_units(self) -> int:
        return self.units

    def work(self) -> Work:
        return Work(self.units, 1, 1)

    def tasks(self, finished, n_jobs):
        todo = [u for u in range(self.units) if str(u) not in finished.keys]
        return [functools.partial(self._unit, u) for u in todo], 1

    def _unit(self, unit: int) -> list[UnitResult]:
        values = np.random.default_rng(unit).random((self.columns, self.rows))
        columns = {"unit": np.full(self.rows, unit, np.int64), "row": np.arange(self.rows, dtype=np.int64)}
        columns.update({f"x{k}": values[k] for k in range(self.columns)})
        return [UnitResult(str(unit), table(columns))]

    @property
    def unit_bytes(self) -> int:
        return self.rows * (self.columns + 2) * 8


def _peak_bytes(run) -> int:
    """Peak of Python and numpy allocations (tracemalloc) plus the peak of Arrow's pool, sampled every ms."""
    arrow_base, arrow_peak, stop = pa.total_allocated_bytes(), [0], threading.Event()

    def sample() -> None:
        while not stop.wait(0.001):
            arrow_peak[0] = max(arrow_peak[0], pa.total_allocated_bytes() - arrow_base)

    sampler = threading.Thread(target=sample, daemon=True)
    tracemalloc.start()
    sampler.start()
    try:
        run()
        return tracemalloc.get_traced_memory()[1] + arrow_peak[0]
    finally:
        stop.set()
        sampler.join()
        tracemalloc.stop()


def test_a_run_to_a_file_holds_a_bounded_share_of_its_rows(tmp_path):
    """160 units of 336 kB (54 MB): the run and its streamed merge hold the buffer, one row group and the
    row keys (16 of the 336 bytes a row), far below all rows (the engine gathered every row before)."""
    scan = _WideScan()
    out = tmp_path / "wide.parquet"
    peak = _peak_bytes(lambda: run_scan(scan, out, checkpoint_seconds=0.0, return_rows=False))
    all_rows = scan.units * scan.unit_bytes
    assert peak < all_rows / 4, f"peak {peak / 1e6:.1f} MB of {all_rows / 1e6:.1f} MB of rows"
    assert pq.ParquetFile(out).metadata.num_rows == scan.units * scan.rows
    store_rows = pq.ParquetFile(out).read(columns=["unit", "row"])
    assert store_rows["unit"].to_pylist() == sorted(store_rows["unit"].to_pylist())


def test_interleaved_units_fall_back_to_the_in_memory_merge(tmp_path):
    """Units whose rows interleave (every unit one row of each of two points) cannot be moved whole."""
    meta = run_metadata("interleaved", {})
    out = tmp_path / "interleaved.parquet"
    store = ResultStore(out, meta, ["point", "start"], flush_seconds=0.0)
    for start in (1, 0):
        rows = table({"point": np.array([0, 1]), "start": np.array([start, start]), "x": np.array([start, -start])})
        store.add(rows, str(start), [])
    store.finalize(return_rows=False)
    rows = pq.ParquetFile(out).read()
    assert rows["point"].to_pylist() == [0, 0, 1, 1] and rows["start"].to_pylist() == [0, 1, 0, 1]
