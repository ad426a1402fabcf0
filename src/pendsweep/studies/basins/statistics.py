"""Statistics of settled runs: survival, settling quantiles, escape rate, fractions, the attractor table."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ...analysis.attractors import (
    Attractor,
    identify_attractors,
)

if TYPE_CHECKING:  # pandas (0.3 s) is imported by the functions that build frames, not by importing this module
    pass
from .rounds import ESCAPE_MIN_EVENTS, SettledRuns


def binomial_stderr(fraction: float, n: int) -> float:
    """Standard error sqrt(f (1 - f) / n) of a fraction estimated from n independent samples."""
    return math.sqrt(fraction * (1.0 - fraction) / n) if n > 0 else math.nan


def survival(settle_periods: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Fraction of runs not yet settled after each of ``times`` [periods] (unsettled: -1, never)."""
    t = np.where(settle_periods < 0, np.inf, settle_periods)
    return (t[None, :] > np.asarray(times)[:, None]).mean(axis=1)


def settling_quantile(settle_periods: np.ndarray, q: float) -> float | None:
    """Quantile ``q`` of the settling time over all runs, unsettled runs counted as never settling.

    None when more than ``1 - q`` of the runs never settled (the quantile lies beyond the cap).
    """
    t = np.sort(np.where(settle_periods < 0, np.inf, settle_periods).astype(float))
    if t.size == 0:
        return None
    value = t[min(t.size - 1, int(math.ceil(q * t.size)) - 1)]
    return float(value) if math.isfinite(value) else None


def escape_rate(settle_periods: np.ndarray, max_periods: int) -> dict[str, Any] | None:
    """Escape rate of a chaotic transient from the survival curve's exponential stretch.

    The stretch runs from the median settling time ``t0`` (the fast, direct
    settlers are past) to the 95 % quantile ``t1`` (or the cap), leaving out
    a sparse tail of slow settlers. With a constant hazard kappa the settling
    times there are exponential, and the censored maximum-likelihood
    estimate is kappa = d / exposure (d settling events in the stretch,
    exposure the periods the runs at risk spent unsettled in it), with
    standard error kappa / sqrt(d). The stretch counts as exponential (a
    transient with a rate exists) when it holds at least
    :data:`ESCAPE_MIN_EVENTS` events and the hazards of its first and last thirds agree
    within 30 % of the overall rate plus 3 combined standard errors.

    Returns
    -------
    dict or None
        ``rate`` and ``stderr`` [1/forcing period], ``lifetime`` (1/rate
        [periods]), ``from``/``to`` (the stretch [periods]), ``events`` and
        ``rate_thirds``; None when there is no exponential stretch.
    """
    t = np.where(settle_periods < 0, np.inf, settle_periods).astype(float)
    t0 = settling_quantile(settle_periods, 0.5) or 0.0
    t1 = settling_quantile(settle_periods, 0.95)
    t1 = float(max_periods) if t1 is None else t1
    if not t1 > t0:
        return None

    def hazard(a: float, b: float) -> tuple[float, int]:
        at_risk = t[t > a]
        events = int(np.count_nonzero(at_risk <= b))
        exposure = float(np.sum(np.minimum(at_risk, b) - a))
        return (events / exposure if exposure > 0 else math.nan), events

    rate, events = hazard(t0, t1)
    if events < ESCAPE_MIN_EVENTS or not rate > 0:
        return None
    edges = np.linspace(t0, t1, 4)
    parts = [hazard(a, b) for a, b in zip(edges[:-1], edges[1:])]
    if min(e for _, e in parts) < 5:
        return None
    rates = np.array([r for r, _ in parts])
    errors = rates / np.sqrt([e for _, e in parts])
    # A constant hazard: no trend from the first third to the last beyond 30 % plus the noise.
    if abs(rates[2] - rates[0]) > 0.3 * rate + 3.0 * math.hypot(errors[0], errors[2]):
        return None
    return {
        "rate": rate,
        "stderr": rate / math.sqrt(events),
        "lifetime": 1.0 / rate,
        "from": t0,
        "to": t1,
        "events": events,
        "rate_thirds": rates.tolist(),
    }


def class_fractions(motion: np.ndarray) -> tuple[dict[str, float], dict[str, float]]:
    """Fraction of runs per motion class and its binomial standard error."""
    n = motion.size
    labels, counts = np.unique(motion.astype(str), return_counts=True)
    order = np.argsort(-counts, kind="stable")
    fractions = {str(labels[i]): counts[i] / n for i in order}
    return fractions, {k: binomial_stderr(f, n) for k, f in fractions.items()}


def summarize(
    runs: SettledRuns, max_periods: int, match_tol: float | None = None
) -> tuple[dict[str, Any], np.ndarray, list[Attractor]]:
    """The basin summary of one parameter point.

    Returns
    -------
    summary : dict
        JSON-able: ``fractions`` and ``stderr`` per motion class (all runs,
        ``unsettled`` included), ``unsettled``, ``settling_periods``
        (``median``, ``q90``; None beyond the cap), ``escape_rate`` (rate per
        forcing period, or None) and ``escape``, ``attractors`` (one entry
        per attractor: id, motion, period, rotation_number, fraction,
        stderr, theta_absmax, section cycle, mirror), ``runs``,
        ``max_periods``, ``diverged``.
    labels : int64[k]
        Attractor id per run (-1: unsettled or failed).
    attractors : list of Attractor
    """
    ok = runs.settled & (runs.status == 0)
    kwargs = {} if match_tol is None else {"tol": match_tol}
    sub, attractors = identify_attractors(
        runs.cycle[ok], runs.period[ok], runs.turns[ok], runs.at_rest[ok], runs.scales[ok], **kwargs
    )
    labels = np.full(runs.status.shape, -1, dtype=np.int64)
    labels[ok] = sub
    n = runs.status.size
    motion = runs.motion
    fractions, stderr = class_fractions(motion)
    table = []
    for a_id, a in enumerate(attractors):
        members = labels == a_id
        f = float(members.mean()) if n else math.nan
        mirror = next((j for j, b in enumerate(attractors) if j != a_id and a.mirror_of(b)), None)
        table.append(
            {
                "id": a_id,
                "motion": a.motion,
                "period": a.period,
                "rotation_number": a.rotation_number,
                "fraction": f,
                "stderr": binomial_stderr(f, n),
                "count": int(members.sum()),
                "theta_absmax": float(np.nanmedian(runs.theta_absmax[members])) if members.any() else math.nan,
                "cycle": a.cycle.tolist(),
                "mirror": mirror,
            }
        )
    escape = escape_rate(runs.escape_periods, max_periods)
    summary = {
        "fractions": fractions,
        "stderr": stderr,
        "unsettled": fractions.get("unsettled", 0.0),
        "settling_periods": {
            "median": settling_quantile(runs.settle_periods, 0.5),
            "q90": settling_quantile(runs.settle_periods, 0.9),
        },
        "escape_periods": {
            "median": settling_quantile(runs.escape_periods, 0.5),
            "q90": settling_quantile(runs.escape_periods, 0.9),
        },
        "escape_rate": None if escape is None else escape["rate"],
        "escape": escape,
        "attractors": table,
        "runs": int(n),
        "diverged": int(np.count_nonzero(runs.status != 0)),
        "max_periods": int(max_periods),
    }
    return summary, labels, attractors
