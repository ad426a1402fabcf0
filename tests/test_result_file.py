"""The result file at the kernel's scale (issue 33 item 1): parts of many units, merged whole, one write for a short run.

A sweep's unit is one point (20 rows); parts used to hold one row group per
unit and the merge read each unit twice, so a 901-point sweep made 900 row
groups and 1,800 reads. These tests pin the layout (a part is one row group
of many units; a run that finishes within its checkpoint interval writes
the final file once, from memory), the checkpoint's promise (a unit waits at
most ``flush_seconds``, counted from the oldest unit waiting, by a writer
thread when no other unit comes), and that every way of merging gives the
file the in-memory merge gives.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import pendsweep.engine.results as results
from pendsweep.engine.columns import _short_text_ranks, repeated, table, to_numpy
from pendsweep.engine.results import METADATA_KEY, ResultStore, run_metadata
from pendsweep.studies.sweep import SweepConfig, run_sweep, value_range

ROWS = ["direction", "point", "period"]


def _unit(point: int, rows: int = 20, shift: float = 0.0, direction: str = "none") -> pa.Table:
    """One unit: ``rows`` periods of one point (its rows contiguous in the sorted order)."""
    periods = np.arange(rows, dtype=np.int64)
    return table(
        {
            "direction": repeated(direction, rows),
            "point": np.full(rows, point, np.int64),
            "period": periods,
            "x": np.sin(point + periods / 7.0) + shift,
        }
    )


def _store(path: Path, **options) -> ResultStore:
    return ResultStore(path, run_metadata("test", {"n": 1}), ROWS, **options)


def _parts(path: Path) -> list[Path]:
    return sorted(path.with_name(path.name + ".parts").glob("part-*.parquet"))


def _expected(points, rows: int = 20) -> pa.Table:
    return pa.concat_tables([_unit(p, rows) for p in sorted(points)]).combine_chunks()


def _final_rows(path: Path) -> pa.Table:
    return pq.ParquetFile(path).read().replace_schema_metadata(None).combine_chunks()


def test_a_run_within_one_checkpoint_writes_the_final_file_once(tmp_path, monkeypatch):
    """901 units of 20 rows finished within the interval: no part, one row group, one write_table call."""
    calls = []
    write_table = pq.ParquetWriter.write_table
    monkeypatch.setattr(pq.ParquetWriter, "write_table", lambda w, *a, **k: calls.append(1) or write_table(w, *a, **k))
    out = tmp_path / "dense.parquet"
    store = _store(out, flush_seconds=3600.0)
    for p in range(901):
        store.add(_unit(p), f"none:{p}:0", [float(p)])
    returned = store.finalize()
    assert store.counts["parts"] == 0 and store.counts["merge_reads"] == 0
    assert len(calls) == 1 and pq.ParquetFile(out).metadata.num_row_groups == 1
    assert _final_rows(out).equals(_expected(range(901)))
    assert returned.combine_chunks().equals(_expected(range(901)))
    meta = json.loads(pq.read_schema(out).metadata[METADATA_KEY])
    assert len(meta["final_states"]) == 901 and meta["final_states"]["none:900:0"] == [900.0]


def test_the_configuration_is_stored_with_the_first_part_not_before(tmp_path):
    """A run that ends within its first interval writes no folder at all; the first part brings config.json."""
    out = tmp_path / "lazy.parquet"
    store = _store(out, flush_seconds=3600.0)
    folder = out.with_name(out.name + ".parts")
    store.add(_unit(0), "none:0:0", [])
    assert not folder.exists()
    store.flush()
    assert json.loads((folder / "config.json").read_text())["config_hash"] == store.config_hash
    store.close()
    resumed = _store(out, flush_seconds=3600.0)
    resumed.finalize(return_rows=False)
    assert _final_rows(out).equals(_expected([0])) and not folder.exists()


def test_parts_hold_many_units_in_one_row_group_and_are_merged_whole(tmp_path):
    """Parts of 300 units: each one row group naming its units and their rows; the part written last and the
    buffer are merged from memory, the others read once each (not once per unit)."""
    out = tmp_path / "parts.parquet"
    store = _store(out, flush_points=300, flush_seconds=3600.0)
    for p in range(901):
        store.add(_unit(p), f"none:{p}:0", [])
    parts = _parts(out)
    assert len(parts) == 3 and store.counts["parts"] == 3
    for k, part in enumerate(parts):
        f = pq.ParquetFile(part)
        meta = json.loads(f.schema_arrow.metadata[METADATA_KEY])
        assert f.metadata.num_row_groups == 1 and f.metadata.num_rows == 300 * 20
        assert meta["units"] == [[f"none:{p}:0", 20] for p in range(300 * k, 300 * (k + 1))]
    store.finalize(return_rows=False)
    assert store.counts["merge_reads"] == 2  # parts 0 and 1; part 2 (the last written) and unit 900 from memory
    assert pq.ParquetFile(out).metadata.num_row_groups == 1
    assert _final_rows(out).equals(_expected(range(901)))
    assert not out.with_name(out.name + ".parts").exists()


def test_a_resumed_store_merges_the_parts_of_the_killed_one(tmp_path):
    """A killed run's parts (on disk only) and the resumed run's units make the uninterrupted file."""
    out = tmp_path / "resumed.parquet"
    first = _store(out, flush_points=100, flush_seconds=3600.0)
    for p in range(250):
        first.add(_unit(p), f"none:{p}:0", [])
    first.close()  # killed: units 200-249 were only buffered
    second = _store(out, flush_seconds=3600.0)
    done, states = second.done([])
    assert set(states) == {f"none:{p}:0" for p in range(200)}
    for p in range(200, 400):
        second.add(_unit(p), f"none:{p}:0", [])
    second.finalize(return_rows=False)
    assert second.counts["merge_reads"] == 2
    assert _final_rows(out).equals(_expected(range(400)))


def test_units_of_two_workers_interleaved_across_parts_are_streamed(tmp_path, monkeypatch):
    """Units finishing out of order (two workers) still move whole, without the in-memory fallback."""
    plans = []
    plan = results.plan_spans
    monkeypatch.setattr(results, "plan_spans", lambda *a: plans.append(plan(*a)) or plans[-1])
    out = tmp_path / "interleaved.parquet"
    store = _store(out, flush_points=4, flush_seconds=3600.0)
    order = [4, 0, 5, 1, 6, 2, 7, 3, 9, 8]
    for p in order:
        store.add(_unit(p), f"none:{p}:0", [])
    store.finalize(return_rows=False)
    assert plans and plans[0] is not None and len(plans[0]) == 10  # every unit a span of its own
    assert _final_rows(out).equals(_expected(range(10)))


def test_a_unit_written_twice_keeps_its_last_copy(tmp_path):
    """A crash between two renames can leave a unit in two parts: the later copy wins, as in memory."""
    out = tmp_path / "twice.parquet"
    store = _store(out, flush_points=3, flush_seconds=3600.0)
    for p in range(3):
        store.add(_unit(p), f"none:{p}:0", [])
    store.add(_unit(2, shift=1.0), "none:2:0", [])  # the same unit again, other values
    store.add(_unit(3), "none:3:0", [])
    rows = store.finalize()
    expected = pa.concat_tables([_unit(0), _unit(1), _unit(2, shift=1.0), _unit(3)]).combine_chunks()
    assert _final_rows(out).equals(expected) and rows.combine_chunks().equals(expected)


def test_parts_of_the_previous_layout_are_merged(tmp_path):
    """A part written before this change (one row group per unit, ``row_group_units``) resumes and merges."""
    out = tmp_path / "old.parquet"
    store = _store(out, flush_seconds=3600.0)
    store.close()
    folder = out.with_name(out.name + ".parts")
    folder.mkdir()
    (folder / "config.json").write_text(json.dumps(store.metadata))
    units = [_unit(p) for p in range(3)]
    meta = {"config_hash": store.config_hash, "final_states": {}, "row_group_units": ["none:0:0", "none:2:0"]}
    rows = results.with_metadata(pa.concat_tables([units[0], units[2]]), meta)
    with pq.ParquetWriter(folder / "part-000000-1.parquet", rows.schema) as writer:
        writer.write_table(rows.slice(0, 20), row_group_size=20)
        writer.write_table(rows.slice(20, 20), row_group_size=20)
    resumed = _store(out, flush_seconds=3600.0)
    assert set(resumed.done([])[1]) == set()  # states were empty; the rows say which units are done
    assert resumed.done(None)[0].num_rows == 40
    resumed.add(units[1], "none:1:0", [])
    resumed.finalize(return_rows=False)
    assert resumed.counts["merge_reads"] == 2
    assert _final_rows(out).equals(_expected(range(3)))


def test_zero_seconds_writes_every_unit_at_once(tmp_path):
    """``checkpoint_seconds=0`` (a remote rig's sweep): each unit is on disk when add returns."""
    out = tmp_path / "rig.parquet"
    store = _store(out, flush_seconds=0.0)
    for p in range(3):
        store.add(_unit(p), f"none:{p}:0", [])
        assert len(_parts(out)) == p + 1
    store.finalize(return_rows=False)
    assert _final_rows(out).equals(_expected(range(3)))


def test_the_checkpoint_counts_from_the_oldest_waiting_unit(tmp_path):
    """Units that finish close together go out in one part, when the oldest has waited the interval;
    a unit never waits longer, and nothing is written before."""
    interval = 2.0
    out = tmp_path / "timed.parquet"
    store = _store(out, flush_seconds=interval)
    t0 = time.monotonic()
    store.add(_unit(0), "none:0:0", [])
    time.sleep(interval / 4)
    store.add(_unit(1), "none:1:0", [])
    assert not _parts(out)
    while not _parts(out) and time.monotonic() - t0 < 30:
        time.sleep(0.01)
    waited = time.monotonic() - t0
    assert interval <= waited < interval + 3.0  # 3 s of slack for a loaded machine's scheduler
    (part,) = _parts(out)
    assert [u[0] for u in json.loads(pq.read_schema(part).metadata[METADATA_KEY])["units"]] == ["none:0:0", "none:1:0"]
    # the next unit starts a new interval of its own, and a kill drops only units younger than it
    store.add(_unit(2), "none:2:0", [])
    store.close()
    assert len(_parts(out)) == 1
    assert set(_store(out).done([])[1]) == {"none:0:0", "none:1:0"}


def test_a_part_being_written_is_merged_from_memory_not_waited_for(tmp_path, monkeypatch):
    """The run ends while the writer thread is still writing a part: the final file is written from the
    units it took, before that write ends; the folder goes only after it."""
    gate, entered = threading.Event(), threading.Event()
    atomic_write_table = results.atomic_write_table

    def slow(table, path, **options):
        if path.name.startswith("part-"):
            entered.set()
            gate.wait(60)
        return atomic_write_table(table, path, **options)

    monkeypatch.setattr(results, "atomic_write_table", slow)
    out = tmp_path / "overlap.parquet"
    store = _store(out, flush_seconds=0.2)
    for p in range(10):
        store.add(_unit(p), f"none:{p}:0", [])
    assert entered.wait(30)
    for p in range(10, 20):
        store.add(_unit(p), f"none:{p}:0", [])
    returned = []
    finishing = threading.Thread(target=lambda: returned.append(store.finalize()))
    finishing.start()
    deadline = time.monotonic() + 30
    while not out.exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert out.exists() and not gate.is_set() and finishing.is_alive()  # written while the part still is
    gate.set()
    finishing.join(30)
    assert _final_rows(out).equals(_expected(range(20))) and returned[0].combine_chunks().equals(_expected(range(20)))
    assert not out.with_name(out.name + ".parts").exists()


def test_a_failed_merge_leaves_the_buffered_units_on_disk(tmp_path, monkeypatch):
    out = tmp_path / "failed.parquet"
    store = _store(out, flush_seconds=3600.0)
    for p in range(5):
        store.add(_unit(p), f"none:{p}:0", [])

    def disk_full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(results, "write_spans", disk_full)
    with pytest.raises(OSError, match="No space"):
        store.finalize()
    store.close()
    assert not out.exists() and len(_parts(out)) == 1
    monkeypatch.undo()
    again = _store(out)
    assert len(again.done([])[1]) == 5
    again.finalize(return_rows=False)
    assert _final_rows(out).equals(_expected(range(5)))


def test_the_buffer_is_written_once_it_holds_a_part_worth_of_rows(tmp_path):
    """The buffer is bounded by bytes as well as by units: wide units go out in parts of about flush_bytes."""
    out = tmp_path / "wide.parquet"
    unit_bytes = _unit(0, rows=1000).nbytes
    store = _store(out, flush_seconds=3600.0, flush_bytes=int(4.5 * unit_bytes))
    for p in range(12):
        store.add(_unit(p, rows=1000), f"none:{p}:0", [])
    assert [pq.ParquetFile(f).metadata.num_rows for f in _parts(out)] == [5000, 5000]
    store.finalize(return_rows=False)
    assert _final_rows(out).equals(_expected(range(12), rows=1000))


def test_a_fresh_sweep_to_a_file_makes_few_parts_and_one_row_group(tmp_path, monkeypatch):
    """A real fresh sweep (batched tasks of 256 points) with one-second checkpoints: at most a part a second
    (plus one), a final file of one row group, rows equal to the run without a file."""
    stores = []
    finalize = ResultStore.finalize
    monkeypatch.setattr(ResultStore, "finalize", lambda s, *a, **k: stores.append(s) or finalize(s, *a, **k))
    config = SweepConfig(
        "alpha", tuple(value_range(0.0, 45.0, 0.1)), mode="fresh", transient_periods=20, record_periods=20
    )
    out = tmp_path / "fresh.parquet"
    t0 = time.monotonic()
    rows = run_sweep(config, out, as_frame=False)
    elapsed = time.monotonic() - t0
    assert stores[0].counts["parts"] <= elapsed + 1
    assert pq.ParquetFile(out).metadata.num_row_groups == 1 and rows.num_rows == 451 * 20
    assert rows.equals(run_sweep(config, as_frame=False))


@pytest.mark.parametrize("large", [False, True])
def test_short_texts_rank_as_python_sorts_them(large):
    """Texts ranked in numpy (fixed-width bytes) rank as Python's code-point order, slices and lengths mixed."""
    rng = np.random.default_rng(7)
    alphabet = ["a", "b", "z", "A", "é", "中", "\x7f", "\x01", " ", "up", "down", "none"]
    for trial in range(300):
        n = int(rng.integers(0, 200))
        longest = 3 if trial % 3 else 9
        texts = ["".join(rng.choice(alphabet, size=int(rng.integers(0, longest)))) for _ in range(n)]
        if trial % 5 == 0:
            texts = ["none"] * n  # one text: the fixed-length shortcut
        values = pa.array(texts, pa.large_string() if large else pa.string())
        if trial % 2 and n > 4:
            values, texts = values.slice(2, n - 3), texts[2 : n - 1]
        rank = {text: i for i, text in enumerate(sorted(set(texts)))}
        got = _short_text_ranks(values)
        if got is None:
            assert max(len(t.encode()) for t in texts) > 16
            continue
        assert got.tolist() == [rank[t] for t in texts]
        assert to_numpy(values).tolist() == [rank[t] for t in texts]
    assert _short_text_ranks(pa.array(["a\x00b", "a"])) is None  # a NUL inside: not by padding
