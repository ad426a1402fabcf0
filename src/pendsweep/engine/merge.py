"""Merge a run's parts, and the units it still holds in memory, into its final parquet file a span at a time.

A part (:class:`pendsweep.engine.results.ResultStore`) holds the rows of many
units, written in one go, and names its units and their row counts, in the
order of its rows, in its metadata (``units``; parts of earlier versions
held one unit per row group and named them in ``row_group_units``). The
final file needs the rows of all parts, without duplicates, sorted by the
row columns. Units cover disjoint, contiguous ranges of row keys (a sweep's
unit is one point, a basin unit a run of starts), so that order is almost
always some order of whole units: :func:`plan_spans` reads only the row-key
columns of every source (one read per part, a few bytes per row) to find
and check it, and joins units that follow each other in one source into
*spans* (a sweep run in order is one span per part). :func:`write_spans`
then copies the spans in that order into one file, in row groups of about
:data:`ROW_GROUP_BYTES`, holding about one part's row group and one output
row group at a time. When the units' keys interleave the plan is None and
the caller merges in memory instead.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .columns import concat_rows, sorted_key_order, strictly_sorted

#: Size of a part and of a row group of the final file [bytes, estimated from the rows' in-memory size]:
#: large enough that a row group costs little per row (a 901-point sweep is one), small enough that the
#: store's buffer and the merge hold a few of them at most.
ROW_GROUP_BYTES = 4 << 20

#: Chunks of fewer rows than this on average are joined into one before a row group is written (a copy,
#: but parquet writes 900 chunks of 20 rows two to three times slower than one of 18,000; chunks of
#: a thousand rows about as fast, so those are written as they are, without the copy).
SMALL_CHUNK_ROWS = 512

#: A unit's key and its number of rows, in the order of a source's rows.
Units = list[tuple[str, int]]


@dataclass(frozen=True)
class Span:
    """Consecutive rows of one source that go to the final file together: ``rows`` rows from row ``start``."""

    source: int
    start: int
    rows: int


class _LastRowGroup:
    """The row group read last (one at a time is held: spans of one row group mostly follow each other)."""

    def __init__(self) -> None:
        self.key: tuple[int, int] | None = None
        self.table: pa.Table | None = None
        self.reads = 0

    def get(self, file: pq.ParquetFile, key: tuple[int, int]) -> pa.Table:
        if key != self.key:
            self.table = None  # let go of the previous one before reading the next
            self.table = file.read_row_group(key[1]).replace_schema_metadata(None)
            self.key = key
            self.reads += 1
        return self.table


def part_units(file: pq.ParquetFile, meta: dict) -> Units | None:
    """A part's units and their row counts in row order, from its metadata (None: it does not say, usably).

    Parts of earlier versions held one unit per row group and named them in
    ``row_group_units``; their row groups' sizes give the counts.
    """
    units = meta.get("units")
    if isinstance(units, list) and all(
        isinstance(u, list) and len(u) == 2 and isinstance(u[0], str) and isinstance(u[1], int) for u in units
    ):
        return [(key, n) for key, n in units]
    names = meta.get("row_group_units")
    if isinstance(names, list) and len(names) == file.num_row_groups:
        return [(str(key), file.metadata.row_group(i).num_rows) for i, key in enumerate(names)]
    return None


class PartSource:
    """A part on disk (its ``pendsweep`` metadata ``meta``): its units and its rows, read a row group at a time."""

    def __init__(self, file: pq.ParquetFile, meta: dict) -> None:
        self.file = file
        self.units = part_units(file, meta)
        sizes = [file.metadata.row_group(i).num_rows for i in range(file.num_row_groups)]
        self._starts = np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)])

    @property
    def schema(self) -> pa.Schema:
        return self.file.schema_arrow.remove_metadata()

    def keys(self, columns: list[str]) -> pa.Table:
        return self.file.read(columns=columns).replace_schema_metadata(None)

    def read_all(self) -> pa.Table:
        return self.file.read().replace_schema_metadata(None)

    def pieces(self, index: int, start: int, rows: int, cache: _LastRowGroup) -> Iterator[pa.Table]:
        """Rows ``start`` to ``start + rows`` as slices of the row groups that hold them."""
        end = start + rows
        group = int(np.searchsorted(self._starts, start, side="right")) - 1
        while start < end:
            first, last = int(self._starts[group]), int(self._starts[group + 1])
            table = cache.get(self.file, (index, group))
            yield table.slice(start - first, min(end, last) - start)
            start, group = last, group + 1


class TableSource:
    """Units still in memory (the store's buffer at the end of a run), as one table."""

    def __init__(self, table: pa.Table, units: Units) -> None:
        self.table = table
        self.units = units

    @property
    def schema(self) -> pa.Schema:
        return self.table.schema.remove_metadata()

    def keys(self, columns: list[str]) -> pa.Table:
        return self.table.select(columns)

    def read_all(self) -> pa.Table:
        return self.table

    def pieces(self, index: int, start: int, rows: int, cache: _LastRowGroup) -> Iterator[pa.Table]:
        yield self.table.slice(start, rows)


Source = PartSource | TableSource


def plan_spans(sources: list[Source], row_columns: list[str]) -> list[Span] | None:
    """The spans whose concatenation is the final file's rows, in order; None when there is none.

    Parameters
    ----------
    sources : list of PartSource or TableSource
        The parts in the order they were written, then the units in memory.
    row_columns : list of str
        Columns that identify one row.

    Returns
    -------
    list of Span or None
        A unit found in several sources (a crash between a part's rename and
        the next checkpoint's) keeps its last copy, as the in-memory merge
        keeps the last copy of each row. None when a source does not name
        its units (or its row counts disagree with them), when two kept rows
        share a key, or when a unit's rows are not contiguous and in order
        among all the sorted rows (units whose key ranges overlap).
    """
    keys, names, counts, owner = [], [], [], []
    for s, source in enumerate(sources):
        if source.units is None:
            return None
        key_table = source.keys(row_columns)
        rows = [n for _, n in source.units]
        if sum(rows) != key_table.num_rows:
            return None
        keys.append(key_table)
        names += [key for key, _ in source.units]
        counts += rows
        owner += [s] * len(rows)
    sizes = np.array(counts, dtype=np.int64)
    source_of = np.array(owner, dtype=np.int64)
    ends = np.cumsum(sizes)
    source_first_row = np.concatenate([[0], np.cumsum([k.num_rows for k in keys], dtype=np.int64)])
    start_in_source = ends - sizes - source_first_row[source_of] if len(sizes) else sizes
    last_copy = {name: position for position, name in enumerate(names)}
    is_last = np.array([last_copy[name] == position for position, name in enumerate(names)], dtype=bool)
    kept = np.flatnonzero(is_last & (sizes > 0))
    if not len(kept):
        return []
    if is_last.all():
        all_keys = pa.concat_tables([k for k in keys if k.num_rows], promote_options="permissive")
    else:  # a unit written twice (a crash between two renames): the kept copies' keys only
        pieces = [keys[source_of[u]].slice(start_in_source[u], sizes[u]) for u in kept]
        all_keys = pa.concat_tables(pieces, promote_options="permissive")
    if strictly_sorted(all_keys, row_columns):
        sequence = kept  # already in order (a sweep run with one worker)
    else:
        order, unique = sorted_key_order(all_keys, row_columns)
        if not unique:
            return None
        kept_sizes = sizes[kept]
        starts = np.concatenate([[0], np.cumsum(kept_sizes)[:-1]])
        unit_of_row = np.repeat(np.arange(len(kept)), kept_sizes)[order]
        # Units in the order their first row appears among the sorted rows.
        first_seen = np.unique(unit_of_row, return_index=True)[1]
        in_order = unit_of_row[np.sort(first_seen)]
        expected = np.concatenate([np.arange(starts[u], starts[u] + kept_sizes[u]) for u in in_order])
        if not np.array_equal(order, expected):
            return None
        sequence = kept[in_order]
    # Units that follow each other in one source make one span.
    src, first, n = source_of[sequence], start_in_source[sequence], sizes[sequence]
    opens = np.ones(len(sequence), dtype=bool)
    opens[1:] = (src[1:] != src[:-1]) | (first[1:] != first[:-1] + n[:-1])
    at = np.flatnonzero(opens)
    return [Span(int(s), int(b), int(r)) for s, b, r in zip(src[at], first[at], np.add.reduceat(n, at), strict=True)]


def unified_schema(sources: list[Source]) -> pa.Schema:
    """The sources' schemas unified as concatenating their tables would (all-null columns take the others' type)."""
    return pa.unify_schemas([source.schema for source in sources], promote_options="permissive")


def conform(table: pa.Table, schema: pa.Schema) -> pa.Table:
    """``table`` with ``schema``'s columns in its order: columns cast, missing ones all null."""
    if table.schema == schema:
        return table
    arrays = [
        table[field.name].cast(field.type) if field.name in table.column_names else pa.nulls(len(table), field.type)
        for field in schema
    ]
    return pa.Table.from_arrays(arrays, schema=schema)


def write_options(schema: pa.Schema) -> dict:
    """Parquet writer options for result rows: dictionary encoding for text columns only.

    Dictionary-encoding columns of measured numbers (every value distinct)
    took three quarters of a write and made the file larger: a dense
    sweep's 18,000 rows were written in 12 ms into 1.24 MB by default, in
    3 ms into 1.05 MB this way, and read back in half the time.
    """
    text = [f.name for f in schema if pa.types.is_string(f.type) or pa.types.is_large_string(f.type)]
    return {"use_dictionary": text}


def compact(table: pa.Table) -> pa.Table:
    """``table`` with its columns in one chunk each where they are in many small ones (:data:`SMALL_CHUNK_ROWS`)."""
    chunks = max((column.num_chunks for column in table.columns), default=0)
    if chunks > 1 and table.num_rows < chunks * SMALL_CHUNK_ROWS:
        return table.combine_chunks()
    return table


def units_table(units: list[tuple[str, pa.Table]]) -> tuple[pa.Table, Units]:
    """Units' rows (``[(key, rows)]``) as one table, small units joined into one chunk; their keys and row counts."""
    counts = [(key, rows.num_rows) for key, rows in units if rows.num_rows]
    return compact(concat_rows([rows for _, rows in units])), counts


def row_bytes(table: pa.Table) -> float:
    """Estimated in-memory bytes per row of ``table`` (at least 1), from its first rows.

    ``nbytes`` of a slice walks every chunk: 40 ms for a buffer of 900
    small units, 0.04 ms for its first 256 rows.
    """
    head = table.slice(0, min(table.num_rows, 256))
    return max(1.0, head.nbytes / max(1, head.num_rows))


def write_spans(
    sink, sources: list[Source], plan: list[Span], schema: pa.Schema, keep: list[pa.Table] | None = None
) -> tuple[int, int]:
    """Copy the spans of ``plan`` into ``sink`` as one parquet file of ``schema`` (metadata included).

    Consecutive spans are gathered into row groups of about
    :data:`ROW_GROUP_BYTES`; at most one such group and one row group of a
    part are held at a time. ``keep`` (a list) receives the row groups
    written, for a caller that returns them. Returns the number of row
    groups written.
    """
    plain = schema.remove_metadata()
    pending: list[pa.Table] = []
    pending_rows, group_rows, written = 0, 0, 0
    cache = _LastRowGroup()
    with pq.ParquetWriter(sink, schema, **write_options(schema)) as writer:

        def write_pending() -> None:
            nonlocal pending_rows, written
            rows = compact(pa.concat_tables(pending))
            pending.clear()
            pending_rows = 0
            writer.write_table(rows, row_group_size=max(1, rows.num_rows))
            written += 1
            if keep is not None:
                keep.append(rows)

        for span in plan:
            for piece in sources[span.source].pieces(span.source, span.start, span.rows, cache):
                if not group_rows:
                    group_rows = max(1, int(ROW_GROUP_BYTES / row_bytes(piece)))
                if pending and pending_rows + piece.num_rows > group_rows:
                    write_pending()
                pending.append(conform(piece, plain))
                pending_rows += piece.num_rows
        if pending:
            write_pending()
    return written, cache.reads
