"""Basins of attraction: many starts integrated until they settle, then grouped into attractors.

The engine is generic over a *stroboscopic map*: any object with

``advance(states, periods, ids) -> (records, states, status)``
    Integrate runs ``ids`` (int64[k], stable run identifiers, e.g. for
    per-run noise seeds) from ``states`` (float64[k, d]) for ``periods``
    forcing periods starting at forcing phase 0; return per-period records
    float64[k, periods, 8] (columns :data:`pendsweep.kernels.RECORD_COLUMNS`),
    the final states float64[k, d] and int64[k] kernel status codes.
``scales_for(ids, records) -> float64[k, 4]``
    Section divisors of runs ``ids`` from their records
    (:func:`pendsweep.analysis.sections.section_scales`).

A one-degree-of-freedom system (the tests' Duffing oscillator) puts its
coordinate and velocity in the ``theta`` columns and leaves the ``y``
columns zero.

:func:`settle_runs` integrates all runs in *rounds* of ``round_periods``
forcing periods (no transient; each round continues from the previous
round's final states) and drops a run as soon as
:func:`pendsweep.analysis.attractors.settling` finds it settled, or after
``max_periods``. Early stop is what makes a 200 x 200 basin map with a
1000-period cap affordable: the cost is the integral of the survival curve,
not ``starts x max_periods``.

:func:`summarize` turns the per-run outcome into the attractor table,
fractions per attractor and per motion class with binomial standard errors,
the settling-time distribution and, when the survival curve has an
exponential tail, the escape rate of the chaotic transient.
"""

from .rounds import (
    CHUNK_STARTS,
    ESCAPE_MIN_EVENTS,
    NOISY_SETTLE_TOL,
    ROUND_PERIODS,
    BackendMap,
    EmulatedMap,
    SettledRuns,
    StroboscopicMap,
    settle_runs,
    settle_tolerance,
)
from .run import (
    ROW_COLUMNS,
    SAMPLINGS,
    BasinConfig,
    BasinScan,
    run_basins,
    runs_frame,
    runs_from_frame,
    system_for,
    unit_key,
)
from .statistics import binomial_stderr, class_fractions, escape_rate, settling_quantile, summarize, survival
from .summary import CONTINUATION_TOL, PAPER_TRANSIENT, point_summary, scan_summary

__all__ = [
    "BackendMap",
    "BasinConfig",
    "BasinScan",
    "CHUNK_STARTS",
    "CONTINUATION_TOL",
    "ESCAPE_MIN_EVENTS",
    "EmulatedMap",
    "NOISY_SETTLE_TOL",
    "PAPER_TRANSIENT",
    "ROUND_PERIODS",
    "ROW_COLUMNS",
    "SAMPLINGS",
    "SettledRuns",
    "StroboscopicMap",
    "binomial_stderr",
    "class_fractions",
    "escape_rate",
    "point_summary",
    "run_basins",
    "runs_frame",
    "runs_from_frame",
    "scan_summary",
    "settle_runs",
    "settle_tolerance",
    "settling_quantile",
    "summarize",
    "survival",
    "system_for",
    "unit_key",
]
