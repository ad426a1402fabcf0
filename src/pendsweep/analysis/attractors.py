"""Settling detection and attractor identification from per-period records.

A trajectory has *settled* when its stroboscopic section (the state at
forcing phase 0, columns ``y_sec .. thetadot_sec`` of
:data:`pendsweep.kernels.RECORD_COLUMNS`) repeats after ``n <= 8`` forcing
periods to :data:`SETTLE_TOL` in every normalised component, and its
per-period rotation count repeats exactly with the same ``n``, over the last
:data:`SETTLE_WINDOW` periods. The comparison is
:func:`pendsweep.analysis.sections.section_difference` (theta wrapped), normalised by
:func:`pendsweep.analysis.sections.section_scales`, as in the motion classifier, so
a settled run and a ``periodic-n`` sweep point mean the same thing. A
rotating orbit is a settled run whose ``n``-period cycle carries a net
number of turns: its rotation number (turns per forcing period) is then
exactly ``turns / n`` and steady. The window (24 periods) is long enough
that a chaotic transient shadowing an unstable periodic orbit is not taken
for settled: it would have to stay within 1e-3 of it for 24 periods, while
the chaotic saddle's Lyapunov exponent (about 0.2-0.6 per period here)
stretches a deviation by e^5 to e^14 over that time.

A rotating orbit whose section does not repeat within 8 periods (a
quasi-periodic rotation, or a cycle longer than 8) is recognised by a
*steady rotation number* instead: the same nonzero number of turns in each
of the last :data:`ROTATION_WINDOW` periods. It is reported with period 0.
Chaotic tumbling reverses or skips turns irregularly and does not pass.

:func:`settling` does this for many runs at once (one compiled pass per run,
:mod:`pendsweep.kernels._settle`) and also returns *when* each run settled: the first period of the
stretch, ending at the record's end, over which the repeat holds. It is the
settling detector of the basin engine (:mod:`pendsweep.studies.basins`), and meant
for an adaptive transient in sweeps (stop integrating a point once it has
settled); :func:`section_scales_many` gives its ``scales`` argument.

:func:`identify_attractors` deduplicates settled runs into attractors. Two
runs are on the same attractor when they have the same cycle length ``n``,
the same rotation number, and one run's section points are within
:data:`MATCH_TOL` (normalised) of the other's, for some cyclic shift: the
two phases of a period-2 orbit are one attractor, while the two senses of a
rotation (mirror images under theta -> -theta) are two.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels._layout import (
    REC_THETADOT_SEC,
    REC_Y_ABSMAX,
    REC_Y_SEC,
)
from ..kernels._settle import settle_check
from ..model.params import ENCODER_RESOLUTION
from .sections import MAX_PERIOD, PERIODIC_TOL, Y_FLOOR, section_difference

#: Largest normalised section mismatch of a repeat [~rad]; the classifier's periodic tolerance.
SETTLE_TOL = PERIODIC_TOL
#: Periods over which the repeat must hold [forcing periods] (>= 2 * MAX_PERIOD + 1: two repeats).
SETTLE_WINDOW = 24
#: Periods of constant, nonzero turns per period that make a steady rotation [forcing periods].
ROTATION_WINDOW = 100
#: A run repeating after n periods whose section comes within this many ``tol`` of repeating after a
#: divisor d of n is still converging to the shorter cycle (a slowly contracting spiral): not settled yet.
AMBIGUITY_FACTOR = 10.0
#: Largest normalised distance between section points of runs on one attractor [~rad].
MATCH_TOL = 0.05

_SEC = slice(REC_Y_SEC, REC_THETADOT_SEC + 1)


@dataclass(frozen=True)
class Settling:
    """What :func:`settling` finds, one entry per run (shape ``(k,)``).

    Attributes
    ----------
    settled : bool[k]
    period : int64[k]
        Cycle length ``n`` in forcing periods (0 when not settled, and for
        a steady rotation without a repeating section).
    turns : int64[k]
        Net full rotations over one cycle (signed; 0 for swinging orbits);
        turns per period for a steady rotation.
    onset : int64[k]
        Index of the first record row of the settled stretch, which runs to
        the end of the record: the section after ``onset + 1`` periods
        repeats ``n`` periods later, and so do all later ones. -1 when not
        settled.
    at_rest : bool[k]
        Settled with max |theta| over the window below the rest threshold
        (the semi-trivial solution).
    ambiguous : bool[k]
        Not settled because the section repeats after ``n`` periods but
        nearly (within ``AMBIGUITY_FACTOR * tol``) after a divisor of ``n``:
        most likely still spiralling into the shorter cycle.
    """

    settled: np.ndarray
    period: np.ndarray
    turns: np.ndarray
    onset: np.ndarray
    at_rest: np.ndarray
    ambiguous: np.ndarray

    @property
    def rotation_number(self) -> np.ndarray:
        """Turns per forcing period (0 where not settled) [1/period]."""
        return np.where(self.settled, self.turns / np.maximum(self.period, 1), 0.0)

    @property
    def motion(self) -> np.ndarray:
        """Motion class per run: ``semi-trivial``, ``periodic-n``, ``rotating`` or ``unsettled``."""
        out = np.full(self.settled.shape, "unsettled", dtype=object)
        for i in np.flatnonzero(self.settled):
            out[i] = motion_label(bool(self.at_rest[i]), int(self.period[i]), int(self.turns[i]))
        return out


def motion_label(at_rest: bool, period: int, turns: int) -> str:
    """Motion class of a settled run (the classifier's labels)."""
    if at_rest:
        return "semi-trivial"
    return "rotating" if turns != 0 else f"periodic-{period}"


def section_scales_many(records: np.ndarray, omega_e, omega_p) -> np.ndarray:
    """:func:`pendsweep.analysis.sections.section_scales` for many runs at once.

    Parameters
    ----------
    records : float64[k, periods, 8]
        Per-period records (NaN rows ignored).
    omega_e, omega_p : float or float64[k]
        Forcing and pendulum angular frequencies [rad/s].

    Returns
    -------
    float64[k, 4]
        ``(Y, w_e Y, 1, w_p)`` per run, ``Y`` the largest |y| [m] of its
        record, at least ``Y_FLOOR`` (1 when the record holds none).
    """
    k = records.shape[0]
    Y = np.fmax.reduce(records[:, :, REC_Y_ABSMAX], axis=1) if records.shape[1] else np.zeros(k)
    Y = np.where(np.isfinite(Y), np.fmax(Y, Y_FLOOR), 1.0)
    return np.stack([Y, omega_e * Y, np.ones(k), np.broadcast_to(omega_p, (k,))], axis=1)


def settling(
    records: np.ndarray,
    scales: np.ndarray,
    *,
    tol: float = SETTLE_TOL,
    window: int = SETTLE_WINDOW,
    max_period: int = MAX_PERIOD,
    rest_threshold: float = ENCODER_RESOLUTION,
    rotation_window: int = ROTATION_WINDOW,
) -> Settling:
    """Whether each run's record ends settled on a periodic (or rotating) orbit.

    Parameters
    ----------
    records : float64[k, periods, 8] or float64[periods, 8]
        Per-period records, columns :data:`pendsweep.kernels.RECORD_COLUMNS`
        (NaN rows, e.g. after a divergence, never count as settled).
    scales : float64[k, 4] or float64[4]
        Section divisors ``(Y [m], w_e Y [m/s], 1, w_p [rad/s])``
        (:func:`pendsweep.analysis.sections.section_scales`).
    tol : float
        Largest normalised mismatch of a repeat [~rad].
    window : int
        The repeat must hold over the last ``window`` periods
        (``window >= 2 * max_period + 1``).
    max_period : int
        Longest cycle searched [forcing periods].
    rest_threshold : float
        Settled runs whose max |theta| over the window is below this [rad]
        are at rest (semi-trivial). The default is one encoder pulse.
    rotation_window : int
        A run not periodic to ``tol`` whose last ``rotation_window`` periods
        each hold the same nonzero number of turns is a steady rotation
        (settled, period 0). Records shorter than this cannot show one.

    Returns
    -------
    Settling
        Arrays of shape ``(k,)`` (``(1,)`` for a single record). The
        smallest repeating ``n`` is reported. A slowly contracting spiral
        around a period-d orbit repeats after a multiple n of d sooner than
        after d (its rotation brings it back); such runs are reported
        ``ambiguous`` rather than settled on ``n`` while the d-repeat
        mismatch is within ``AMBIGUITY_FACTOR * tol``.
    """
    rec = np.ascontiguousarray(records, dtype=np.float64)
    single = rec.ndim == 2
    if single:
        rec = rec[None]
    k = rec.shape[0]
    if window < 2 * max_period + 1:
        raise ValueError(f"window = {window} must be >= 2 * max_period + 1 = {2 * max_period + 1}")
    sc = np.ascontiguousarray(np.broadcast_to(np.asarray(scales, dtype=np.float64), (k, 4)))
    out = np.empty((k, 6), dtype=np.int64)
    settle_check(rec, sc, tol, window, max_period, rest_threshold, rotation_window, AMBIGUITY_FACTOR, out)
    return Settling(
        out[:, 0].astype(bool), out[:, 1].copy(), out[:, 2].copy(), out[:, 3].copy(),
        out[:, 4].astype(bool), out[:, 5].astype(bool),
    )  # fmt: skip


@dataclass(frozen=True)
class Attractor:
    """One attractor found by :func:`identify_attractors`.

    Attributes
    ----------
    motion : str
        ``semi-trivial``, ``periodic-n`` or ``rotating``.
    period : int
        Cycle length [forcing periods]; 0 for a steady rotation whose
        section does not repeat within ``MAX_PERIOD``.
    turns : int
        Net rotations per cycle (per period when ``period`` is 0; signed:
        the sense of a rotating orbit).
    cycle : float64[max(period, 1), 4]
        Section points ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])``
        of the cycle, from the representative run (for period 0: its last
        section point).
    scales : float64[4]
        The representative run's section divisors.
    """

    motion: str
    period: int
    turns: int
    cycle: np.ndarray
    scales: np.ndarray

    @property
    def rotation_number(self) -> float:
        """Turns per forcing period."""
        return self.turns / max(self.period, 1)

    def mirror_of(self, other: Attractor, tol: float = MATCH_TOL) -> bool:
        """Whether ``other`` is this attractor's image under theta -> -theta (same y)."""
        if other.period != self.period or other.turns != -self.turns:
            return False
        if self.period == 0:  # steady rotations are identified by their rotation number alone
            return True
        image = other.cycle * np.array([1.0, 1.0, -1.0, -1.0])
        return bool(cycle_distance(self.cycle[None], image, self.scales)[0] < tol)


def cycle_distance(cycles: np.ndarray, reference: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """Normalised distance of each cycle to ``reference``, minimised over cyclic shifts.

    ``cycles`` is ``(k, n, 4)``, ``reference`` ``(n, 4)``; the distance is the
    largest component of :func:`~pendsweep.analysis.sections.section_difference` over
    the cycle's points.
    """
    n = reference.shape[0]
    best = np.full(cycles.shape[0], np.inf)
    for shift in range(n):
        d = np.abs(section_difference(cycles, np.roll(reference, shift, axis=0), scales)).max(axis=(1, 2))
        best = np.minimum(best, d)
    return best


def identify_attractors(
    cycles: np.ndarray,
    period: np.ndarray,
    turns: np.ndarray,
    at_rest: np.ndarray,
    scales: np.ndarray,
    tol: float = MATCH_TOL,
    known: list[Attractor] | None = None,
) -> tuple[np.ndarray, list[Attractor]]:
    """Group settled runs into attractors.

    Parameters
    ----------
    cycles : float64[k, MAX_PERIOD, 4]
        Each run's last ``period[i]`` section points in rows ``0 .. period[i]-1``
        (later rows ignored).
    period, turns : int64[k]
        From :class:`Settling`.
    at_rest : bool[k]
        Runs at rest all belong to the one semi-trivial attractor (with
        Coulomb friction the pendulum sticks at slightly different angles).
    scales : float64[k, 4]
        Section divisors per run.
    tol : float
        Matching tolerance [normalised].
    known : list of Attractor, optional
        Attractors to match first (e.g. from a neighbouring parameter value);
        new ones are appended to a copy.

    Returns
    -------
    labels : int64[k]
        Index into ``attractors`` per run.
    attractors : list of Attractor
    """
    k = len(period)
    attractors = list(known or [])
    labels = np.full(k, -1, dtype=np.int64)
    rest_ids = [i for i, a in enumerate(attractors) if a.motion == "semi-trivial"]
    if at_rest.any():
        if not rest_ids:
            first = int(np.flatnonzero(at_rest)[0])
            attractors.append(Attractor("semi-trivial", 1, 0, cycles[first, :1].copy(), scales[first].copy()))
            rest_ids = [len(attractors) - 1]
        labels[at_rest] = rest_ids[0]
    todo = ~at_rest

    def assign(a_id: int) -> None:
        a = attractors[a_id]
        same = np.flatnonzero(todo & (period == a.period) & (turns == a.turns) & (labels < 0))
        if same.size and a.period == 0:  # steady rotations: one attractor per rotation number
            labels[same] = a_id
        elif same.size:
            d = cycle_distance(cycles[same, : a.period], a.cycle, a.scales)
            labels[same[d < tol]] = a_id

    for a_id, a in enumerate(attractors):
        if a.motion != "semi-trivial":
            assign(a_id)
    # Periodic runs first, so that a steady rotation can join the periodic rotation it is approaching.
    for periodic in (True, False):
        while True:
            remaining = np.flatnonzero(todo & (labels < 0) & ((period > 0) == periodic))
            if remaining.size == 0:
                break
            r = int(remaining[0])
            n = int(period[r])
            if n == 0:
                joined = _join_periodic_rotation(cycles[remaining, 0], turns[remaining], attractors, tol)
                labels[remaining] = joined
                if (joined >= 0).all():
                    break
                r = int(remaining[joined < 0][0])
            attractors.append(
                Attractor(
                    motion_label(False, n, int(turns[r])),
                    n,
                    int(turns[r]),
                    cycles[r, : max(n, 1)].copy(),
                    scales[r].copy(),
                )
            )
            assign(len(attractors) - 1)
            labels[r] = len(attractors) - 1  # always matches itself; guards against NaN sections
    return labels, attractors


def _join_periodic_rotation(
    points: np.ndarray, turns: np.ndarray, attractors: list[Attractor], tol: float
) -> np.ndarray:
    """For steady rotations (one section point each, ``turns`` per period): the periodic rotating
    attractor with the same rotation number whose cycle passes within ``tol`` of the point, else -1."""
    out = np.full(len(points), -1, dtype=np.int64)
    for a_id, a in enumerate(attractors):
        if a.motion != "rotating" or a.period == 0:
            continue
        same = np.flatnonzero((out < 0) & (turns == a.rotation_number))
        if same.size:
            d = np.abs(section_difference(points[same, None, :], a.cycle[None], a.scales)).max(axis=2).min(axis=1)
            out[same[d < tol]] = a_id
    return out
