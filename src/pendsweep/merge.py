"""Merge a run's parts into its final parquet file one row group at a time.

Every part (:class:`pendsweep.results.ResultStore`) holds each of its units
as one row group and names the unit of each row group in its metadata. The
final file needs the rows of all parts, without duplicates, sorted by the
row columns. Units cover disjoint, contiguous ranges of row keys (a sweep's
unit is one point, a basin unit a run of starts), so that order is almost
always some order of whole row groups: :func:`plan_row_groups` reads only
the row-key columns (a few bytes per row) to find and check it, and
:func:`write_row_groups` then copies the row groups in that order into one
file, holding about one row group at a time. When the row groups' keys interleave
the plan is None and the caller merges in memory instead.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .columns import sorted_key_order


@dataclass(frozen=True)
class RowGroup:
    """One unit's rows in a part: the part's index in the merge, the row group's index in the part."""

    part: int
    index: int
    unit: str


def plan_row_groups(
    parts: list[pq.ParquetFile], units: list[list[str] | None], row_columns: list[str]
) -> list[RowGroup] | None:
    """The row groups whose concatenation is the final file's rows, in order; None when there is none.

    Parameters
    ----------
    parts : list of pyarrow.parquet.ParquetFile
        The parts, in the order they were written.
    units : list of (list of str or None)
        Per part, the unit key of each of its row groups (None: a part that
        does not say, written before parts held one unit per row group).
    row_columns : list of str
        Columns that identify one row.

    Returns
    -------
    list of RowGroup or None
        A unit found in several parts (a crash between a part's rename and
        the next checkpoint's) keeps its last copy, as the in-memory merge
        keeps the last copy of each row. None when a part does not name its
        row groups' units, when two kept rows share a key, or when a row
        group's rows are not contiguous and in order among all the sorted
        rows (row groups whose key ranges overlap).
    """
    groups = []
    for p, (part, names) in enumerate(zip(parts, units)):
        if names is None or len(names) != part.num_row_groups:
            return None
        groups += [RowGroup(p, i, name) for i, name in enumerate(names)]
    last_copy = {group.unit: position for position, group in enumerate(groups)}
    kept = [group for position, group in enumerate(groups) if last_copy[group.unit] == position]
    if not kept:
        return kept
    keys = pa.concat_tables(
        [parts[g.part].read_row_group(g.index, columns=row_columns) for g in kept], promote_options="permissive"
    )
    order, unique = sorted_key_order(keys, row_columns)
    if not unique:
        return None
    sizes = np.array([parts[g.part].metadata.row_group(g.index).num_rows for g in kept])
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    group_of_row = np.repeat(np.arange(len(kept)), sizes)[order]
    # Groups in the order their first row appears among the sorted rows.
    first_seen = np.unique(group_of_row, return_index=True)[1]
    sequence = group_of_row[np.sort(first_seen)]
    expected = np.concatenate([np.arange(starts[g], starts[g] + sizes[g]) for g in sequence])
    if not np.array_equal(order, expected):
        return None
    return [kept[g] for g in sequence]


def unified_schema(parts: list[pq.ParquetFile]) -> pa.Schema:
    """The parts' schemas unified as concatenating their tables would (all-null columns take the others' type)."""
    return pa.unify_schemas([part.schema_arrow.remove_metadata() for part in parts], promote_options="permissive")


def conform(table: pa.Table, schema: pa.Schema) -> pa.Table:
    """``table`` with ``schema``'s columns in its order: columns cast, missing ones all null."""
    if table.schema == schema:
        return table
    arrays = [
        table[field.name].cast(field.type) if field.name in table.column_names else pa.nulls(len(table), field.type)
        for field in schema
    ]
    return pa.Table.from_arrays(arrays, schema=schema)


#: Fewest rows of a row group of the final file [rows]: smaller units (a Hopf scan's single rows)
#: are gathered up to it, so that a file of a million one-row units does not carry a million row groups.
MIN_ROW_GROUP_ROWS = 4096


def write_row_groups(sink, parts: list[pq.ParquetFile], plan: list[RowGroup], schema: pa.Schema) -> None:
    """Copy the row groups of ``plan`` into ``sink`` as one parquet file of ``schema`` (metadata included).

    At most :data:`MIN_ROW_GROUP_ROWS` rows plus one unit's are held at a
    time: consecutive small units are written as one row group.
    """
    plain = schema.remove_metadata()
    pending: list[pa.Table] = []
    with pq.ParquetWriter(sink, schema) as writer:

        def write_pending() -> None:
            rows = pa.concat_tables(pending)
            writer.write_table(rows, row_group_size=max(1, rows.num_rows))
            pending.clear()

        for group in plan:
            rows = parts[group.part].read_row_group(group.index).replace_schema_metadata(None)
            pending.append(conform(rows, plain))
            if sum(t.num_rows for t in pending) >= MIN_ROW_GROUP_ROWS:
                write_pending()
        if pending:
            write_pending()
