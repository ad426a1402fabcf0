"""A sweep's finished units as rows: their keys and long-form result rows, one row per recorded period.

The rows' columns are the results file's (README "Results files"); they are
built from whole numpy columns for many units at once and handed to the
scan engine (:class:`pendsweep.scan.UnitResult`) one slice per unit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa

from .backends import PointRun
from .columns import repeated_each, table
from .kernels import RECORD_COLUMNS
from .kernels._layout import RECORD_INDEX
from .scan import UnitResult


def unit_key(direction: str, point: int, start: int) -> str:
    """Identifier of one unit of work in result stores and resume bookkeeping."""
    return f"{direction}:{int(point)}:{int(start)}"


@dataclass
class PointResult:
    """One finished unit of work, ready to be written."""

    direction: str
    point: int
    start: int
    value: float
    run: PointRun
    kicked: bool
    motion: str = ""
    settled: bool = False
    transient_used: int = 0
    #: On a noisy backend: the record's measured section jitter and the periodicity tolerance applied
    #: [normalised, ~rad] (:class:`pendsweep.classify.SectionNoise`; NaN where not measured). None: noise-free.
    section_noise: float | None = None
    periodic_tol: float | None = None

    @property
    def key(self) -> str:
        return unit_key(self.direction, self.point, self.start)


def result_rows(results: list[PointResult], parameter: str, adaptive: bool) -> pa.Table:
    """Long-form rows of units, one row per recorded period, the units one after another.

    ``parameter`` names the swept value's column; ``adaptive`` (``--transient
    auto``) adds the columns ``settled`` and ``transient_periods_used``; units
    of a noisy backend add ``section_noise`` and ``periodic_tol``.
    Built from whole columns for all the units at once: a dense sweep's
    task holds hundreds of units, and a table each cost more than their
    classification (:func:`unit_results` slices this one instead).
    """
    counts = [r.run.records.shape[0] for r in results]
    total = sum(counts)
    records = np.concatenate([r.run.records for r in results]) if results else np.empty((0, len(RECORD_COLUMNS)))

    def per_row(values: list, dtype) -> np.ndarray:
        return np.repeat(np.array(values, dtype=dtype), counts)

    first_rows = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64) if results else np.zeros(0, np.int64)
    columns: dict[str, Any] = {
        parameter: per_row([r.value for r in results], np.float64),
        "direction": repeated_each([r.direction for r in results], counts),
        "point": per_row([r.point for r in results], np.int64),
        "start": per_row([r.start for r in results], np.int64),
        "period": np.arange(total, dtype=np.int64) - np.repeat(first_rows, counts),
    }
    for j, name in enumerate(RECORD_COLUMNS):
        columns[name] = records[:, j]
    columns["rotations"] = np.nan_to_num(records[:, RECORD_INDEX["rotations"]]).astype(np.int64)
    columns["kicked"] = per_row([r.kicked for r in results], np.bool_)
    columns["status"] = repeated_each([r.run.status.value for r in results], counts)
    columns["motion"] = repeated_each([r.motion for r in results], counts)
    if results and results[0].run.round_trip is not None:  # a remote rig: the protocol's timing [s]
        for k, name in enumerate(("round_trip_p50", "round_trip_p99", "round_trip_max")):
            columns[name] = per_row([r.run.round_trip[k] for r in results], np.float64)
    if results and results[0].section_noise is not None:  # a noisy backend: what the classifier measured
        columns["section_noise"] = per_row([r.section_noise for r in results], np.float64)
        columns["periodic_tol"] = per_row([r.periodic_tol for r in results], np.float64)
    if adaptive:
        columns["settled"] = per_row([r.settled for r in results], np.bool_)
        columns["transient_periods_used"] = per_row([r.transient_used for r in results], np.int64)
    return table(columns)


def unit_results(results: list[PointResult], parameter: str, adaptive: bool) -> list[UnitResult]:
    """The finished units, ready to be written: their rows sliced from one table (:func:`result_rows`), final states."""
    rows = result_rows(results, parameter, adaptive)
    units, offset = [], 0
    for r in results:
        n = r.run.records.shape[0]
        units.append(UnitResult(r.key, rows.slice(offset, n), r.run.state.tolist()))
        offset += n
    return units
