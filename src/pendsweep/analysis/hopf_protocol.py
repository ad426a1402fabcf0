"""The simulated Hopf protocol: settle, kick the pendulum, fit its envelope's growth, bisect in alpha.

The ``simulate`` method of :mod:`pendsweep.studies.hopf` (see there for why the window is long), on any
registered backend, many points in lockstep.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..backends.status import Status
from ..kernels import N_RECORD_COLUMNS
from ..kernels._layout import (
    REC_ROTATIONS,
    REC_THETA_ABSMAX,
    REC_THETA_SEC,
    REC_THETADOT_SEC,
)
from ..model.params import ENCODER_RESOLUTION, ModelParams
from .classify import at_rest
from .semi_trivial import alpha_hopf_analytic, semi_trivial_response

#: Envelope [rad] up to which the kicked pendulum is treated as linear (or 4 kicks, if larger).
LINEAR_LIMIT = 0.1


def kicked_records_many(
    backend, params: list[ModelParams], kick: float, settle_periods: int, periods: int
) -> tuple[np.ndarray, list[Status]]:
    """Kick the pendulum off the semi-trivial solution and record what follows, for many points.

    The one place the simulate method touches a backend. The oscillator
    starts on its steady response, with the pendulum at rest, and runs
    ``settle_periods`` (to settle any backend-specific states); then the
    pendulum is kicked (:meth:`~pendsweep.backends.Backend.kick`). Both
    stages go through the backend's ``run_points``, so a batched backend
    integrates all points at once.

    Returns
    -------
    records : float64[n, periods, 8]
        Per-period records after the kick (``pendsweep.kernels.RECORD_COLUMNS``:
        the envelope is ``theta_absmax``, the section ``theta_sec, thetadot_sec``).
    status : list of Status
    """
    starts = []
    for q in params:
        Y = semi_trivial_response(q)
        starts.append(backend.initial_state(q, Y.imag, q.omega_e * Y.real, 0.0, 0.0))
    settled = backend.run_points(params, np.asarray(starts), settle_periods, 1)
    records = np.full((len(params), periods, N_RECORD_COLUMNS), np.nan)
    status = [s.status for s in settled]
    ok = [i for i, s in enumerate(settled) if s.status is Status.OK]
    kicked = np.asarray([backend.kick(settled[i].state, kick) for i in ok])
    for i, r in zip(ok, backend.run_points([params[i] for i in ok], kicked, 0, periods) if ok else []):
        records[i], status[i] = r.records, r.status
    return records, status


def kicked_records(
    backend, params: ModelParams, kick: float, settle_periods: int, periods: int
) -> tuple[np.ndarray, Status]:
    """:func:`kicked_records_many` for one point: records ``(periods, 8)`` and status."""
    records, status = kicked_records_many(backend, [params], kick, settle_periods, periods)
    return records[0], status[0]


def envelope_growth_rate(records: np.ndarray, omega_p: float, linear_limit: float) -> float:
    """Growth rate [1/period] of the kicked pendulum's envelope, two-multiplier fit.

    The stroboscopic pendulum state ``x_k = (theta_k, thetadot_k / omega_p)``
    of a linear(ised) pendulum obeys ``x_{k+1} = A x_k`` exactly, so its
    envelope is ``|c1 mu1^k + c2 mu2^k|`` - beating included. ``A`` is fitted
    by least squares over the periods before the envelope first exceeds
    ``linear_limit`` rad (at least 3), and the rate is ``log max|eig A|``
    (``log`` of the largest Floquet multiplier modulus). ``inf`` when the
    pendulum rotates.
    """
    if np.nansum(np.abs(records[:, REC_ROTATIONS])) > 0:
        return math.inf
    big = np.flatnonzero(records[:, REC_THETA_ABSMAX] > linear_limit)
    n = max(3, int(big[0]) if big.size else records.shape[0])
    x = np.vstack([records[:n, REC_THETA_SEC], records[:n, REC_THETADOT_SEC] / omega_p])
    A = np.linalg.lstsq(x[:, :-1].T, x[:, 1:].T, rcond=None)[0].T
    return float(np.log(np.abs(np.linalg.eigvals(A)).max()))


def hopf_simulate(
    params: ModelParams,
    backend,
    *,
    kick: float = 0.01,
    periods: int = 200,
    settle_periods: int = 10,
    tol: float = 0.1,
    alpha_max: float = 500.0,
    rest_threshold: float = ENCODER_RESOLUTION,
) -> dict[str, Any]:
    """Bisection on alpha with the kick-and-growth-rate criterion (module docstring).

    Alpha is above the boundary when :func:`envelope_growth_rate` is
    positive and the pendulum has not come to rest (final period's envelope
    not below ``rest_threshold`` [rad], one encoder pulse by default; see
    :func:`pendsweep.analysis.classify.at_rest`; Coulomb friction can stop it). The search starts at
    1.25 x Eq. (12) (only as a first guess) and doubles until the pendulum
    grows; alpha = 0 is stable by definition. Returns a dict with
    ``alpha_H`` (bracket midpoint), ``bracket_lo/hi`` [N],
    ``growth_below/above`` (growth rates at the bracket ends [1/period]),
    ``runs`` and ``status``.
    """
    return hopf_simulate_many(
        [params],
        backend,
        kick=kick,
        periods=periods,
        settle_periods=settle_periods,
        tol=tol,
        alpha_max=alpha_max,
        rest_threshold=rest_threshold,
    )[0]


def hopf_simulate_many(
    params: list[ModelParams],
    backend,
    *,
    kick: float = 0.01,
    periods: int = 200,
    settle_periods: int = 10,
    tol: float = 0.1,
    alpha_max: float = 500.0,
    rest_threshold: float = ENCODER_RESOLUTION,
) -> list[dict[str, Any]]:
    """:func:`hopf_simulate` for many points, their bisections in lockstep.

    Every round gathers the next trial alpha of each unfinished search and
    integrates them in one :func:`kicked_records_many` call, so the batched
    kernel runs all points at once. Each search takes the same decisions as
    it would alone.
    """
    searches = [_bisection(q, tol, alpha_max) for q in params]
    results: list[dict[str, Any] | None] = [None] * len(params)
    trials = {i: next(s) for i, s in enumerate(searches)}
    while trials:
        points = list(trials)
        trial_params = [params[i].replace(alpha=trials[i]) for i in points]
        records, status = kicked_records_many(backend, trial_params, kick, settle_periods, periods)
        for k, i in enumerate(points):
            growth = math.nan
            if status[k] is Status.OK:
                rate = envelope_growth_rate(records[k], params[i].omega_p, max(LINEAR_LIMIT, 4.0 * kick))
                resting = at_rest(records[k][-1, REC_THETA_ABSMAX], rest_threshold)
                growth = min(rate, 0.0) if resting else rate
            try:
                trials[i] = searches[i].send((growth, status[k]))
            except StopIteration as finished:
                results[i] = finished.value
                del trials[i]
    return results


def _bisection(params: ModelParams, tol: float, alpha_max: float):
    """The bisection of :func:`hopf_simulate` as a generator.

    Yields trial amplitudes [N]; is sent ``(growth rate, status)`` for each;
    returns the result dict (``StopIteration.value``).
    """
    runs = 0
    lo, g_lo = 0.0, math.nan
    hi = 1.25 * alpha_hopf_analytic(params) or 1.0
    while True:
        g_hi, status = yield hi
        runs += 1
        if status is not Status.OK:
            return _simulate_row(math.nan, lo, hi, g_lo, g_hi, runs, status.value)
        if g_hi > 0.0:
            break
        lo, g_lo, hi = hi, g_hi, 2.0 * hi
        if hi > alpha_max:
            return _simulate_row(math.nan, lo, math.nan, g_lo, math.nan, runs, "not-found")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        g, status = yield mid
        runs += 1
        if status is not Status.OK:
            return _simulate_row(math.nan, lo, hi, g_lo, g_hi, runs, status.value)
        if g > 0.0:
            hi, g_hi = mid, g
        else:
            lo, g_lo = mid, g
    return _simulate_row(0.5 * (lo + hi), lo, hi, g_lo, g_hi, runs, "ok")


def _simulate_row(alpha, lo, hi, g_lo, g_hi, runs, status) -> dict[str, Any]:
    return dict(
        alpha_H=alpha, bracket_lo=lo, bracket_hi=hi, growth_below=g_lo, growth_above=g_hi, runs=runs, status=status
    )
