"""Summaries of finished basin scans, per value and along the parameter."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ...analysis.attractors import (
    Attractor,
    cycle_distance,
)

if TYPE_CHECKING:  # pandas (0.3 s) is imported by the functions that build frames, not by importing this module
    import pandas as pd
from .run import ROW_COLUMNS, BasinConfig, runs_from_frame
from .statistics import binomial_stderr, summarize, survival

CONTINUATION_TOL = 0.5
#: The paper's transient [forcing periods]: the scan reports the fraction still unsettled after it.
PAPER_TRANSIENT = 100


def point_summary(df_point: pd.DataFrame, max_periods: int) -> tuple[dict[str, Any], np.ndarray, list[Attractor]]:
    """:func:`summarize` of one point's stored rows, plus the fraction unsettled after 100 periods.

    That fraction is NaN when the runs stopped earlier (``max_periods`` < 100): a
    run unsettled at its cap may settle before 100.
    """
    runs = runs_from_frame(df_point)
    summary, labels, attractors = summarize(runs, max_periods)
    n = runs.status.size
    s100 = i100 = math.nan
    if max_periods >= PAPER_TRANSIENT:
        s100 = float(survival(runs.settle_periods, np.array([PAPER_TRANSIENT]))[0])
        i100 = float(survival(runs.escape_periods, np.array([PAPER_TRANSIENT]))[0])
    summary["unsettled_after_100"] = s100
    summary["unsettled_after_100_stderr"] = binomial_stderr(s100, n)
    summary["irregular_after_100"] = i100
    summary["irregular_after_100_stderr"] = binomial_stderr(i100, n)
    return summary, labels, attractors


def scan_summary(config: BasinConfig, df: pd.DataFrame) -> tuple[dict[str, Any], pd.DataFrame]:
    """Summaries per point, attractors matched across parameter values, and rows with an ``attractor`` column.

    Attractors at consecutive values are the same branch when they have the
    same cycle length and turns and their cycles lie within
    :data:`CONTINUATION_TOL` of each other (the closest one wins); each
    branch gets a global id. The returned rows carry that id per start
    (-1: unsettled or failed).

    Returns
    -------
    summary : dict
        For one value, the point's summary (see :func:`summarize`) with
        ``parameter`` and ``value`` added. For several: ``parameter``,
        ``values``, ``classes`` and ``classes_stderr`` (fraction per motion
        class per value), ``unsettled_after_100`` (+ ``_stderr``),
        ``attractors`` (global id, motion, period, rotation_number,
        ``fractions`` and ``stderr`` per value, ``theta_absmax`` per value)
        and ``points`` (each point's own summary).
    rows : DataFrame
    """
    df = df.sort_values(ROW_COLUMNS, kind="stable").reset_index(drop=True)
    points, globals_, previous = [], [], []  # previous: [(global id, Attractor)] at the last value
    global_labels = np.full(len(df), -1, dtype=np.int64)
    for point, value in enumerate(config.values):
        rows = np.flatnonzero(df["point"].to_numpy() == point)
        summary, labels, attractors = point_summary(df.iloc[rows], config.max_periods)
        mapping, current, taken = {}, [], set()
        for a_id, a in enumerate(attractors):
            best, best_d = None, CONTINUATION_TOL
            for g, b in previous:
                if g in taken or b.period != a.period or b.turns != a.turns or b.motion != a.motion:
                    continue
                d = 0.0 if a.period == 0 else float(cycle_distance(a.cycle[None], b.cycle, a.scales)[0])
                if d < best_d:
                    best, best_d = g, d
            if best is None:
                best = len(globals_)
                globals_.append(
                    {"id": best, "motion": a.motion, "period": a.period, "rotation_number": a.rotation_number}
                )
            taken.add(best)
            mapping[a_id] = best
            current.append((best, a))
        previous = current
        for entry in summary["attractors"]:
            entry["global_id"] = mapping[entry["id"]]
        ok = labels >= 0
        global_labels[rows[ok]] = [mapping[i] for i in labels[ok]]
        summary.update(parameter=config.parameter, value=value)
        points.append(summary)
    out = df.copy()
    out["attractor"] = global_labels
    out = out.drop(columns=["cycle", "scales"])
    if len(config.values) == 1:
        return points[0], out
    classes = sorted({c for p in points for c in p["fractions"]})
    for g in globals_:
        per_point = [next((e for e in p["attractors"] if e["global_id"] == g["id"]), None) for p in points]
        g["fractions"] = [e["fraction"] if e else 0.0 for e in per_point]
        g["stderr"] = [e["stderr"] if e else binomial_stderr(0.0, p["runs"]) for e, p in zip(per_point, points)]
        g["theta_absmax"] = [e["theta_absmax"] if e else None for e in per_point]
    summary = {
        "parameter": config.parameter,
        "values": list(config.values),
        "classes": {c: [p["fractions"].get(c, 0.0) for p in points] for c in classes},
        "classes_stderr": {
            c: [binomial_stderr(p["fractions"].get(c, 0.0), p["runs"]) for p in points] for c in classes
        },
        "unsettled_after_100": [p["unsettled_after_100"] for p in points],
        "unsettled_after_100_stderr": [p["unsettled_after_100_stderr"] for p in points],
        "irregular_after_100": [p["irregular_after_100"] for p in points],
        "irregular_after_100_stderr": [p["irregular_after_100_stderr"] for p in points],
        "escape_rate": [p["escape_rate"] for p in points],
        "attractors": globals_,
        "points": points,
    }
    return summary, out
