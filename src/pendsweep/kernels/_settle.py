"""Settling checks over per-period records, one compiled pass per run.

:func:`settle_check` decides whether a run's record ends on a repeating
section (or a steady rotation), and :func:`update_near_since` keeps, for each
cycle length, the period since which a run's section has stayed close to
repeating. Both read the records of :mod:`._layout` (``REC_*`` columns) in
place, run by run, with no temporaries: the numpy formulation they replace
made several passes over every run's history between the basin rounds, as
costly as a third of the integration. They run on one thread: a round's
checks take about a millisecond per 4096 runs, less than waking the
other threads costs on a loaded machine (7 ms with two threads, one core busy).

A section repeats after ``n`` periods when every component of the
normalised difference (``(a - b) / scale``, theta wrapped to (-pi, pi]) is
below the tolerance and both periods hold the same number of turns. A NaN
anywhere (a diverged run) never repeats.
"""

import math

import numba as nb
import numpy as np

from ._layout import REC_ROTATIONS, REC_THETA_ABSMAX, REC_Y_SEC


@nb.njit(cache=True, nogil=True, inline="always")
def _mismatch(rec, a, b, inverse_scales):
    """Largest normalised component of section ``a`` minus section ``b`` of one run's record (NaN-propagating).

    ``inverse_scales`` are the reciprocals of the section divisors: a product
    differs from the quotient by at most one rounding (1e-16 relative), which
    moves no comparison against a tolerance of 1e-3 that a record can reach.
    """
    worst = 0.0
    for c in range(4):
        d = (rec[a, REC_Y_SEC + c] - rec[b, REC_Y_SEC + c]) * inverse_scales[c]
        if c == 2 and abs(d) > math.pi:  # theta, wrapped to (-pi, pi] (within it, d is its own wrap)
            d = math.atan2(math.sin(d), math.cos(d))
        d = abs(d)
        if math.isnan(d):
            return d
        worst = max(worst, d)
    return worst


@nb.njit(cache=True, nogil=True, inline="always")
def _inverse(scales):
    """The reciprocals of one run's four section divisors, as a tuple (no allocation per run)."""
    return 1.0 / scales[0], 1.0 / scales[1], 1.0 / scales[2], 1.0 / scales[3]


@nb.njit(cache=True, nogil=True, inline="always")
def _repeats(rec, j, n, inverse_scales, tol):
    """Whether the section after period ``j + n`` matches the one after period ``j`` (same turns)."""
    return _mismatch(rec, j + n, j, inverse_scales) < tol and rec[j + n, REC_ROTATIONS] == rec[j, REC_ROTATIONS]


@nb.njit(cache=True, nogil=True)
def _settle_one(rec, inverse_scales, tol, window, max_period, rotation_window, ambiguity):
    """``(settled, period, turns, onset, ambiguous)`` of one run's record ``rec`` (periods, 8)."""
    periods = rec.shape[0]
    first = periods - window
    for n in range(1, max_period + 1):
        repeating = True
        for j in range(first, periods - n):
            if not _repeats(rec, j, n, inverse_scales, tol):
                repeating = False
                break
        if not repeating:
            continue
        # A slowly contracting spiral around a shorter cycle d | n repeats after n first: wait for d.
        for d in range(1, n):
            if n % d == 0:
                near = True  # every pair within the ambiguity band (NaN: not near)
                for j in range(first, periods - d):
                    if not _mismatch(rec, j + d, j, inverse_scales) < ambiguity * tol:
                        near = False
                        break
                if near:
                    return False, 0, 0, -1, True
        onset = 0
        for j in range(periods - n - 1, -1, -1):  # the repeating stretch that ends at the record's end
            if not _repeats(rec, j, n, inverse_scales, tol):
                onset = j + 1
                break
        turns = 0.0
        for j in range(periods - n, periods):
            turns += rec[j, REC_ROTATIONS]
        return True, n, int(np.rint(turns)), onset, False
    if periods >= rotation_window:
        last = rec[periods - 1, REC_ROTATIONS]
        steady = last != 0.0
        for j in range(periods - rotation_window, periods):
            steady = steady and rec[j, REC_ROTATIONS] == last
        if steady:
            onset = 0
            for j in range(periods - 1, -1, -1):
                if rec[j, REC_ROTATIONS] != last:
                    onset = j + 1
                    break
            return True, 0, int(np.rint(last)), onset, False
    return False, 0, 0, -1, False


@nb.njit(cache=True, nogil=True)
def settle_check(records, scales, tol, window, max_period, rest_threshold, rotation_window, ambiguity, out):
    """Settling of every run of ``records`` (k, periods, 8) with section divisors ``scales`` (k, 4).

    Fills ``out`` (int64[k, 6]) with ``settled, period, turns, onset,
    at_rest, ambiguous`` per run, as :func:`pendsweep.analysis.attractors.settling`
    documents them. Records shorter than ``window`` periods are not settled.
    """
    k, periods = records.shape[0], records.shape[1]
    for i in range(k):
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4], out[i, 5] = 0, 0, 0, -1, 0, 0
        if periods < window:
            continue
        rec = records[i]
        settled, period, turns, onset, ambiguous = _settle_one(
            rec, _inverse(scales[i]), tol, window, max_period, rotation_window, ambiguity
        )
        swing = np.nan  # the window's largest swing, NaN rows ignored (numpy's fmax)
        for j in range(periods - window, periods):
            v = rec[j, REC_THETA_ABSMAX]
            if not (math.isnan(v) or v <= swing):
                swing = v
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = settled, period, turns, onset
        out[i, 4] = settled and swing < rest_threshold
        out[i, 5] = ambiguous


@nb.njit(cache=True, nogil=True)
def update_near_since(records, scales, new_periods, first_row, tol, near_since, rows):
    """For each run and cycle length n, the first period since which its section has stayed near repeating.

    ``records`` (k, periods, 8) ends with the ``new_periods`` periods of the
    latest round; ``first_row`` is the periods elapsed before its first row.
    For every pair whose later section lies in the latest round and that
    does not repeat to ``tol`` after n periods, ``near_since[rows[i], n - 1]``
    becomes the period after it (``near_since`` int64[runs, max_period],
    updated in place).
    """
    k, periods = records.shape[0], records.shape[1]
    max_period = near_since.shape[1]
    for i in range(k):
        rec = records[i]
        inverse_scales = _inverse(scales[i])
        for n in range(1, max_period + 1):
            start = max(periods - new_periods - n, 0)  # earliest pair whose later section is new
            for j in range(periods - n - 1, start - 1, -1):
                if not _repeats(rec, j, n, inverse_scales, tol):
                    near_since[rows[i], n - 1] = first_row + j + 1
                    break


@nb.njit(cache=True, nogil=True)
def carry_history(buffer, keep, held, following):
    """``following[i, :held] = buffer[keep[i], -held:]``: the next round's history of the runs kept.

    Row by row, without the temporary a fancy index makes (numpy's ``take``
    into a strided ``out`` copied element by element: 8 s a round for 1e5 runs),
    and element by element: numba compiles a slice-to-slice assignment with a
    formatted shape-mismatch error, seconds of a cold start.
    """
    start = buffer.shape[1] - held
    for i in range(keep.size):
        source = buffer[keep[i]]
        for j in range(held):
            for c in range(buffer.shape[2]):
                following[i, j, c] = source[start + j, c]
