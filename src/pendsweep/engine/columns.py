"""Rows as pyarrow columns built straight from numpy buffers, and read back the same way.

pyarrow imports pandas (0.2 to 0.3 s, a fifth of a one-point sweep) the
first time it converts numpy arrays or Python values (``pa.array``,
``pa.table``, ``Array.to_numpy``, ``pq.read_table``, ``pyarrow.compute``),
though not on import. The scans build their rows, write, merge and summarise
them through the functions here, which hand Arrow the numpy memory as
buffers and never take those paths, so a command that never asks for a
DataFrame never pays for pandas.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq


def column(values: np.ndarray | pa.Array) -> pa.Array:
    """A 1-D numeric or bool numpy array as an Arrow array (numbers share its memory; bools are bit-packed)."""
    if isinstance(values, pa.Array):
        return values
    a = np.ascontiguousarray(values)
    if a.ndim != 1:
        raise ValueError(f"a column is one-dimensional, got shape {a.shape}")
    if not a.dtype.isnative:  # Arrow buffers are little-endian native memory
        a = a.astype(a.dtype.newbyteorder("="))
    if a.dtype == np.bool_:
        bits = np.packbits(a, bitorder="little")
        return pa.Array.from_buffers(pa.bool_(), len(a), [None, pa.py_buffer(bits)])
    if a.dtype.kind not in "fiu":
        raise TypeError(f"column of dtype {a.dtype}: give numbers or bools (strings through repeated)")
    return pa.Array.from_buffers(pa.from_numpy_dtype(a.dtype), len(a), [None, pa.py_buffer(a)])


def repeated(text: str, n: int) -> pa.Array:
    """``n`` copies of ``text`` as an Arrow string array."""
    return repeated_each([text], [n])


def repeated_each(texts: list[str], counts: list[int]) -> pa.Array:
    """``texts[i]`` repeated ``counts[i]`` times, one text after another, as an Arrow string array."""
    encoded = [text.encode() for text in texts]
    lengths = np.repeat(np.array([len(e) for e in encoded], dtype=np.int64), counts)
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int32)
    data = b"".join(e * c for e, c in zip(encoded, counts))
    return pa.Array.from_buffers(pa.string(), len(lengths), [None, pa.py_buffer(offsets), pa.py_buffer(data)])


def table(columns: dict[str, np.ndarray | pa.Array]) -> pa.Table:
    """A Table of named columns (numpy arrays through :func:`column`, Arrow arrays as they are)."""
    return pa.Table.from_arrays([column(c) for c in columns.values()], names=list(columns))


#: String columns up to this length are ranked in Python; longer ones through
#: Arrow's dictionary encoding (which loads ``pyarrow.compute``, 25 ms, a cost a
#: small sweep's start-up should not pay; a million rows take 10 ms instead of 0.4 s).
PYTHON_RANK_ROWS = 65536


#: Longest text ranked in numpy by :func:`_short_text_ranks` [bytes]: a sweep's ``direction`` has 4.
SHORT_TEXT_BYTES = 16


def _short_text_ranks(values: pa.Array) -> np.ndarray | None:
    """Sort ranks of a column of short texts, in numpy (None where it does not apply: long texts, many rows, NULs).

    Each text, zero-padded to the longest (to 8 bytes: one big-endian
    integer), becomes a fixed-width byte string; those sort as the texts do
    (UTF-8 bytes sort in code-point order, and trailing zeros are padding as
    long as no text holds a NUL). A sweep's 18,000 ``direction`` texts take
    a fraction of a millisecond, against 6 ms through Python.
    """
    n = len(values)
    if n > PYTHON_RANK_ROWS:
        return None
    wide = pa.types.is_large_string(values.type)
    offsets = np.frombuffer(values.buffers()[1], np.int64 if wide else np.int32, count=values.offset + n + 1)
    offsets = offsets[values.offset :].astype(np.int64)
    lengths = np.diff(offsets)
    width = int(lengths.max()) if n else 0
    if width == 0:
        return np.zeros(n, np.int64)
    if width > SHORT_TEXT_BYTES:
        return None
    data = np.frombuffer(values.buffers()[2], np.uint8)
    if not data[offsets[0] : offsets[-1]].all():  # a NUL inside a text
        return None
    longest = width
    width = 8 if width <= 8 else width  # up to 8 bytes: one big-endian integer, which sorts as the bytes do
    if (lengths == longest).all():  # texts of one length (``none``): their bytes are the rows already
        padded = np.zeros((n, width), np.uint8)
        padded[:, :longest] = data[offsets[0] : offsets[-1]].reshape(n, longest)
    else:
        column_ = np.arange(width)
        gathered = data[np.minimum(offsets[:-1, None] + column_, len(data) - 1)]
        padded = np.where(column_ < lengths[:, None], gathered, 0).astype(np.uint8)
    fixed = padded.view(">u8" if width == 8 else f"S{width}").ravel()
    if (fixed == fixed[0]).all():
        return np.zeros(n, np.int64)
    return np.unique(fixed, return_inverse=True)[1].astype(np.int64).ravel()


def to_numpy(values: pa.Array | pa.ChunkedArray) -> np.ndarray:
    """A numeric or bool Arrow column (no nulls) as a new numpy array; a string column as sort ranks.

    A string becomes the rank of its value among the column's distinct
    values in sorted order, so the codes compare and sort as the strings
    do, which is what sorting, grouping and duplicate checks need.
    """
    if isinstance(values, pa.ChunkedArray):
        values = values.combine_chunks()
    if values.null_count:
        raise ValueError(f"column of {values.type} has {values.null_count} nulls")
    if pa.types.is_string(values.type) or pa.types.is_large_string(values.type):
        ranks = _short_text_ranks(values)
        if ranks is not None:
            return ranks
        if len(values) > PYTHON_RANK_ROWS:
            encoded = values.dictionary_encode()
            words = encoded.dictionary.to_pylist()
            rank = np.argsort(np.argsort(np.array(words, dtype=object)))
            return rank[to_numpy(encoded.indices)].astype(np.int64)
        texts = values.to_pylist()
        rank = {text: i for i, text in enumerate(sorted(set(texts)))}
        return np.fromiter((rank[text] for text in texts), np.int64, len(texts))
    n, offset = len(values), values.offset
    if pa.types.is_boolean(values.type):
        bits = np.frombuffer(values.buffers()[1], np.uint8) if n else np.zeros(0, np.uint8)
        return np.unpackbits(bits, bitorder="little", count=offset + n)[offset:].astype(bool)
    dtype = np.dtype(values.type.to_pandas_dtype())
    if not n:
        return np.empty(0, dtype)
    return np.frombuffer(values.buffers()[1], dtype, count=offset + n)[offset:].copy()


def concat_rows(tables: list[pa.Table]) -> pa.Table:
    """Tables concatenated; types unified (all-null or string columns from pandas frames) (empty: no columns)."""
    tables = [t for t in tables if t.num_columns]
    if not tables:
        return pa.table({})
    first = tables[0].schema
    if all(t.schema.equals(first) for t in tables[1:]):  # the usual case: ten times faster than promoting
        return pa.concat_tables(tables)
    return pa.concat_tables(tables, promote_options="permissive")


def read_parquet(path: Path) -> pa.Table:
    """A whole parquet file as a Table (``pq.read_table`` goes through pyarrow.dataset, which imports pandas)."""
    return pq.ParquetFile(path).read()


def _key_order(table_: pa.Table, keys: list[str]) -> tuple[np.ndarray, list[np.ndarray]]:
    """The stable ascending order of the rows by ``keys`` (first key first), and the sorted key codes."""
    codes = [to_numpy(table_[k]) for k in keys]
    order = np.lexsort(codes[::-1])
    return order, [c[order] for c in codes]


def sort_rows(table_: pa.Table, keys: list[str]) -> pa.Table:
    """``table_`` stably sorted by ``keys`` (ascending; strings in code-point order); as it is when already sorted."""
    if table_.num_rows < 2:
        return table_
    order, _ = _key_order(table_, keys)
    if np.array_equal(order, np.arange(len(order))):
        return table_  # the usual case (rows come in order): no take, which imports pyarrow.compute
    return table_.take(column(order))


def sorted_key_order(table_: pa.Table, keys: list[str]) -> tuple[np.ndarray, bool]:
    """The stable ascending order of the rows by ``keys``, and whether no two rows agree on every key."""
    if table_.num_rows < 2:
        return np.arange(table_.num_rows), True
    order, ordered = _key_order(table_, keys)
    same = np.ones(table_.num_rows - 1, dtype=bool)
    for c in ordered:
        same &= c[1:] == c[:-1]
    return order, not same.any()


def strictly_sorted(table_: pa.Table, keys: list[str]) -> bool:
    """Whether the rows of ``table_`` are in ascending order by ``keys`` and no two agree on every key.

    The usual case of a merge, checked without sorting: the key codes and
    two flags a row, not the order and sorted copies of :func:`sorted_key_order`.
    """
    if table_.num_rows < 2:
        return True
    ahead = np.zeros(table_.num_rows - 1, dtype=bool)  # the row is after the one before it on an earlier key
    tied = np.ones(table_.num_rows - 1, dtype=bool)  # the two agree on every key so far
    for k in keys:
        c = to_numpy(table_[k])
        ahead |= tied & (c[1:] > c[:-1])
        tied &= c[1:] == c[:-1]
    return bool(ahead.all())


def has_duplicate_rows(table_: pa.Table, keys: list[str]) -> bool:
    """Whether two rows of ``table_`` agree on every column of ``keys``."""
    return not sorted_key_order(table_, keys)[1]
