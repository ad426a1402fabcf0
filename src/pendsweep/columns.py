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


def has_duplicate_rows(table_: pa.Table, keys: list[str]) -> bool:
    """Whether two rows of ``table_`` agree on every column of ``keys``."""
    return not sorted_key_order(table_, keys)[1]
