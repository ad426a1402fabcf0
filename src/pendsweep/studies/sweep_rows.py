"""A sweep's finished units as rows: their keys and long-form result rows, one row per recorded period.

The rows' columns are the results file's (README "Results files"); they are
built from whole numpy columns for many units at once and handed to the
scan engine (:class:`pendsweep.engine.scan.UnitResult`) one slice per unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa

from ..analysis.classify import Motion, at_rest
from ..backends import PointRun
from ..engine.columns import repeated_each, table, to_numpy
from ..engine.scan import UnitResult
from ..kernels import RECORD_COLUMNS
from ..kernels._layout import RECORD_INDEX


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
    #: [normalised, ~rad] (:class:`pendsweep.analysis.classify.SectionNoise`; NaN where not measured). None: noise-free.
    section_noise: float | None = None
    periodic_tol: float | None = None
    #: A remote rig's continuous test: whether the point began a new session after a resume (None: not a rig test).
    restarted: bool | None = None
    #: A rig's continuous test: replies that came more than a step after their simulated time (None: not a rig test).
    late_ticks: int | None = None

    @property
    def key(self) -> str:
        return unit_key(self.direction, self.point, self.start)


def result_rows(results: list[PointResult], parameter: str, adaptive: bool) -> pa.Table:
    """Long-form rows of units, one row per recorded period, the units one after another.

    ``parameter`` names the swept value's column; ``adaptive`` (``--transient
    auto``) adds the columns ``settled`` and ``transient_periods_used``; units
    of a noisy backend add ``section_noise`` and ``periodic_tol``, those of a
    rig's continuous test ``restarted`` and ``late_ticks``.
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
    if results and results[0].restarted is not None:  # a rig's continuous test: where the branch broke
        columns["restarted"] = per_row([r.restarted for r in results], np.bool_)
        columns["late_ticks"] = per_row([r.late_ticks for r in results], np.int64)
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


def classified_fields(motion: Motion, backend) -> dict:
    """The :class:`PointResult` fields a classification fills: the label and, on a noisy backend, its noise."""
    if not backend.noisy:
        return {"motion": motion.label}
    # at rest or not finished, the label rests on no repeat: no noise to show
    noise = None if motion.label in ("semi-trivial", "n/a") else motion.noise
    return {
        "motion": motion.label,
        "section_noise": math.nan if noise is None else noise.largest_jitter,
        "periodic_tol": math.nan if noise is None else noise.applied_tolerance,
    }


def resume_info(done_rows: pa.Table, states: dict[str, list[float]], threshold: float) -> dict[str, dict]:
    """Per finished unit: its final state, whether it ended OK and at rest."""
    if not done_rows.num_rows:
        return {}
    rows: dict[str, list[int]] = {}  # unit key -> its rows, in table order
    columns = zip(done_rows["direction"].to_pylist(), to_numpy(done_rows["point"]), to_numpy(done_rows["start"]))
    for row, (d, p, s) in enumerate(columns):
        rows.setdefault(unit_key(d, p, s), []).append(row)
    ok_rows = np.array([status == "ok" for status in done_rows["status"].to_pylist()])
    swings = to_numpy(done_rows["theta_absmax"])
    info = {}
    for key, index in rows.items():
        ok = bool(ok_rows[index].all())
        info[key] = {
            "state": states.get(key),
            "ok": ok and states.get(key) is not None,
            "at_rest": ok and at_rest(swings[index], threshold),
        }
    return info
