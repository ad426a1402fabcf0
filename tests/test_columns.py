"""Rows built from numpy buffers (pendsweep.engine.columns) against pyarrow's own conversions, and the start-up they save."""

import subprocess
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from pendsweep.engine import columns
from pendsweep.engine.columns import column, has_duplicate_rows, read_parquet, repeated, sort_rows, table, to_numpy


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 1000])
def test_columns_round_trip_through_parquet_bit_for_bit(tmp_path, n):
    """Floats (NaN, inf, -0.0 included), ints and bools of any length come back identical, also from slices."""
    rng = np.random.default_rng(n)
    floats = rng.normal(size=n)
    if n >= 4:
        floats[:4] = [np.nan, np.inf, -np.inf, -0.0]
    ints = rng.integers(-(2**62), 2**62, size=n)
    bools = rng.random(n) < 0.5
    rows = table({"f": floats, "i": ints, "b": bools, "s": repeated("ok", n)})
    assert rows.schema == pa.schema([("f", pa.float64()), ("i", pa.int64()), ("b", pa.bool_()), ("s", pa.string())])
    pq.write_table(rows, tmp_path / "t.parquet")
    back = read_parquet(tmp_path / "t.parquet")
    assert back.schema == rows.schema and back.drop_columns(["f"]).equals(rows.drop_columns(["f"]))
    assert to_numpy(back["f"]).tobytes() == floats.tobytes()
    assert np.array_equal(to_numpy(back["i"]), ints)
    assert np.array_equal(to_numpy(back["b"]), bools)
    assert back["s"].to_pylist() == ["ok"] * n
    # pyarrow's own conversions agree (they import pandas, which is fine here)
    peer = pa.table({"f": floats, "i": ints, "b": bools, "s": pa.array(["ok"] * n, pa.string())})
    assert peer.drop_columns(["f"]).equals(rows.drop_columns(["f"]))
    assert peer["f"].to_numpy().tobytes() == rows["f"].to_numpy().tobytes() == floats.tobytes()
    if n > 3:  # a sliced column starts at an offset inside its buffers
        part = rows.slice(3, n - 5)
        assert np.array_equal(to_numpy(part["b"]), bools[3 : n - 2])
        assert np.array_equal(to_numpy(part["i"]), ints[3 : n - 2])


def test_foreign_byte_order_is_converted():
    values = np.arange(6, dtype=">f8") / 3
    assert np.array_equal(to_numpy(column(values)), values)


def test_column_refuses_what_it_cannot_represent():
    with pytest.raises(ValueError, match="one-dimensional"):
        column(np.zeros((2, 2)))
    with pytest.raises(TypeError, match="dtype <U1"):
        column(np.array(["a"]))
    with pytest.raises(ValueError, match="nulls"):
        to_numpy(pa.array([1.0, None]))


@pytest.mark.parametrize("python_rank_rows", [65536, 0], ids=["ranked-in-python", "dictionary-encoded"])
def test_sort_and_duplicates_agree_with_pyarrow(monkeypatch, python_rank_rows):
    """sort_rows is pyarrow's stable sort_by (strings in code-point order); has_duplicate_rows its group_by count.

    Both ways of ranking strings (small columns in Python, long ones through
    Arrow's dictionary encoding) are checked against pyarrow.
    """
    monkeypatch.setattr(columns, "PYTHON_RANK_ROWS", python_rank_rows)
    rng = np.random.default_rng(3)
    for trial in range(40):
        n = int(rng.integers(0, 60))
        directions = rng.choice(["up", "down", "none", "Up", "ü"], size=n).tolist()
        rows = pa.table(
            {
                "direction": pa.array(directions, pa.string()),
                "point": rng.integers(0, 4, size=n),
                "period": rng.integers(0, 3, size=n),
                "tag": np.arange(n),  # tells stable orders apart
            }
        )
        keys = ["direction", "point", "period"][: 1 + trial % 3]
        expected = rows.sort_by([(k, "ascending") for k in keys])
        assert sort_rows(rows, keys).equals(expected)
        assert sort_rows(expected, keys) is expected  # already sorted: returned as it is
        distinct = rows.group_by(keys).aggregate([]).num_rows if n else 0
        assert has_duplicate_rows(rows, keys) == (distinct < n)


def test_string_codes_sort_as_the_strings():
    codes = to_numpy(pa.chunked_array([pa.array(["up", "down"]), pa.array(["none", "up"])]))
    assert codes.tolist() == [2, 0, 1, 2]


def test_a_sweep_command_loads_no_pandas_tqdm_or_pyarrow_compute(tmp_path):
    """The cause of a one-point sweep's start-up, checked without timing it (the timing is in `make bench`)."""
    heavy = ("pandas", "pyarrow.compute", "tqdm", "scipy.signal", "matplotlib", "pendsweep.studies.basins")
    code = (
        "import sys; from click.testing import CliRunner; from pendsweep.cli import main; "
        "r = CliRunner().invoke(main, ['alpha', '--from', '10', '--to', '10.5', '--transient-periods', '2', "
        "'--record-periods', '2', '-o', 'o.parquet', '--no-progress']); assert r.exit_code == 0, r.output; "
        f"print(sorted(m for m in {heavy!r} if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
    assert has_duplicate_rows(read_parquet(tmp_path / "o.parquet"), ["direction", "point", "start", "period"]) is False
