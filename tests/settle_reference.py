"""The straightforward numpy settling checks: the reference the compiled ones (``kernels._settle``) must reproduce.

This was the basin engine's own code before the checks were fused into one
compiled pass per run; tests compare the two on records with every outcome.
"""

import numpy as np

from pendsweep.analysis.attractors import AMBIGUITY_FACTOR, Settling
from pendsweep.analysis.sections import section_difference
from pendsweep.kernels._layout import REC_ROTATIONS, REC_THETA_ABSMAX, REC_THETADOT_SEC, REC_Y_SEC

_SEC = slice(REC_Y_SEC, REC_THETADOT_SEC + 1)


def repeat_mask(records, scales, n, tol):
    """``mask[i, j]``: run i's section after period ``j + n`` matches the one after period ``j`` (same turns)."""
    sc = np.asarray(scales, dtype=np.float64)
    sc = sc[:, None, :] if sc.ndim == 2 else sc
    sections, rotations = records[:, :, _SEC], records[:, :, REC_ROTATIONS]
    mismatch = np.abs(section_difference(sections[:, n:], sections[:, :-n], sc)).max(axis=2)
    return (mismatch < tol) & (rotations[:, n:] == rotations[:, :-n])


def near_since_update(buffer, scales, periods, first_row, tol, near_since, active, max_period):
    """The basin rounds' bookkeeping of when each run's section last broke an n-repeat."""
    for n in range(1, max_period + 1):
        recent = buffer[:, -(periods + n) :]
        near = repeat_mask(recent, scales, n, tol)
        broken = ~near
        any_break = broken.any(axis=1)
        last_break = near.shape[1] - 1 - np.argmax(broken[:, ::-1], axis=1)
        pair_first = first_row + buffer.shape[1] - recent.shape[1]
        near_since[active[any_break], n - 1] = pair_first + last_break[any_break] + 1


def settling(rec, scales, *, tol, window, max_period, rest_threshold, rotation_window):
    """:func:`pendsweep.analysis.attractors.settling`, written with numpy passes over all runs."""
    k, periods, _ = rec.shape
    sc = np.broadcast_to(np.asarray(scales, dtype=np.float64), (k, 4))[:, None, :]
    settled = np.zeros(k, dtype=bool)
    period = np.zeros(k, dtype=np.int64)
    turns = np.zeros(k, dtype=np.int64)
    onset = np.full(k, -1, dtype=np.int64)
    if periods < window:
        return Settling(settled, period, turns, onset, np.zeros(k, dtype=bool), np.zeros(k, dtype=bool))
    sections = rec[:, :, _SEC]
    rotations = rec[:, :, REC_ROTATIONS]
    first = periods - window

    def repeats(rows, n, start):
        return repeat_mask(rec[rows, start:], sc[rows], n, tol)

    deferred = np.zeros(k, dtype=bool)
    for n in range(1, max_period + 1):
        candidates = np.flatnonzero(~settled & ~deferred)
        if candidates.size == 0:
            break
        new = candidates[repeats(candidates, n, first).all(axis=1)]
        for d in (d for d in range(1, n) if n % d == 0):
            if new.size:
                a, b = sections[new, first + d :], sections[new, first : periods - d]
                near = np.abs(section_difference(a, b, sc[new])).max(axis=(1, 2)) < AMBIGUITY_FACTOR * tol
                deferred[new[near]] = True
                new = new[~near]
        if new.size == 0:
            continue
        settled[new] = True
        period[new] = n
        broken = ~repeats(new, n, 0)
        last_break = np.where(broken.any(axis=1), broken.shape[1] - 1 - np.argmax(broken[:, ::-1], axis=1), -1)
        onset[new] = last_break + 1
        turns[new] = np.rint(rotations[new, periods - n :].sum(axis=1)).astype(np.int64)
    if periods >= rotation_window:
        tail = rotations[:, periods - rotation_window :]
        steady = ~settled & ~deferred & (tail == tail[:, -1:]).all(axis=1) & (tail[:, -1] != 0)
        steady_rows = np.flatnonzero(steady)
        if steady_rows.size:
            settled[steady_rows] = True
            turns[steady_rows] = np.rint(rotations[steady_rows, -1]).astype(np.int64)
            changed = rotations[steady_rows] != rotations[steady_rows, -1:]
            onset[steady_rows] = np.where(changed.any(axis=1), periods - np.argmax(changed[:, ::-1], axis=1), 0)
    swing = np.fmax.reduce(rec[:, first:, REC_THETA_ABSMAX], axis=1)
    at_rest = settled & (swing < rest_threshold)
    return Settling(settled, period, turns, onset, at_rest, deferred & ~settled)
