"""The stroboscopic section of a record: its normalisation, its repeats, and a noisy record's own noise.

The normalised section is ``(y/Y, ydot/(w_e Y), theta, thetadot/w_p)`` with
``Y`` the largest |y| of the record, so all four components are
dimensionless and of the size of theta in rad; theta differences are
wrapped to (-pi, pi].

Noisy records (backends with ``noisy`` True: a rig's sensors, the
substructured loop's load cell, encoder and LVDT). An encoder alone
quantises theta to 0.0013 rad, and the load cell's noise jitters the whole
loop, so a rig's section cannot repeat to 1e-3 even where its motion is
periodic. :func:`measured_noise` measures each record's own noise. For
every cycle n it takes the n-differences of the normalised section and of
each period's largest |theta| (``theta_absmax``: a swing that grows or
decays shows there even when the section, sampled near a zero crossing,
hides it), and their rms per component over sqrt 2, the jitter of one
section. A cycle's level is its largest jitter, a quantised channel
counted at least at its step. The smallest level over the cycles is the
record's noise floor, and the smallest cycle whose level is within
:data:`NOISE_FLOOR_RATIO` of it is the record's cycle. The record repeats
after that cycle within its noise when the jitter looks like noise: at
most :data:`NOISE_MAX` (chaos in bands and tori are larger), no drift (the
n-differences' mean within :data:`NOISE_DRIFT_SIGMAS` standard errors of
0) and no smooth motion (each component's autocorrelation, averaged over
lags 1..n, below :data:`NOISE_SMOOTHNESS`: independent jitter gives
-1/(2n), a slow drift, a decaying swing or a torus's rotation near +1),
and every n-difference is within the tolerance the jitter sets:
:data:`NOISE_SIGMAS` jitters plus the channel's step, never below
:data:`PERIODIC_TOL`. A record that repeats to :data:`PERIODIC_TOL` is
periodic whatever its noise. :class:`SectionNoise` keeps what was measured
(the classifier's rows show its jitter and the tolerance applied). Limits: a period-2n orbit whose halves differ by less than the
floor ratio reads as period n, and a torus or band chaos smaller than the
noise reads as periodic, as the record cannot tell them apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..kernels._layout import REC_Y_ABSMAX
from ..model.params import ModelParams

#: Largest section mismatch [normalised, ~rad] still counted as a repeat.
PERIODIC_TOL = 1e-3
#: Longest period searched [forcing periods].
MAX_PERIOD = 8
#: Smallest oscillator amplitude a section is normalised by [m]: an unforced
#: oscillator decaying to rest would otherwise be measured against its own
#: vanishing amplitude and never repeat (1 nm is far below any displacement sensor).
Y_FLOOR = 1e-9
#: Noisy records: the largest section jitter accepted as noise [normalised, ~rad], about twice the largest
#: of the default substructured loop's on the period-2 branch of Fig. 11(a1) (5e-4 to 1.4e-3 over 8 seeds
#: at 20-36 N). A larger jitter could hide a small torus or band chaos (20 sections cannot tell them from
#: noise), so it is not taken for noise: such a record gets the extension and Lyapunov evidence, or on a
#: rig, which cannot re-run a point, stays ``transient``. Near a bifurcation, where the orbit's weak
#: stability amplifies the noise, and on rigs three times noisier than the default, points read so ...
NOISE_MAX = 0.003
#: ... a component's tolerance is this many times its measured jitter (the largest of ~20 n-differences
#: of Gaussian jitter lies near 3.5 jitters) ...
NOISE_SIGMAS = 5.0
#: ... once the jitter looks like noise: no drift (mean n-difference within this many standard errors of 0) ...
NOISE_DRIFT_SIGMAS = 4.0
#: ... and no smooth motion (every component's autocorrelation of the n-differences, averaged over
#: lags 1..n, below this).
NOISE_SMOOTHNESS = 0.5
#: A cycle's level (largest component jitter) counts as the record's noise floor within this factor of
#: the smallest over all cycles (estimates from 12 to 18 differences differ by up to ~1.6 by chance);
#: a period-2n orbit whose two halves differ by less is read as period n, as the noise allows.
NOISE_FLOOR_RATIO = 2.0
#: Fewest lag-n pairs of n-differences a cycle n needs to measure the noise.
NOISE_MIN_PAIRS = 6

_THETA = 2  # theta's place in a section (y, ydot, theta, thetadot)


@dataclass(frozen=True)
class SectionNoise:
    """A record's measured section noise (:func:`cycle_noise`, :func:`measured_noise`).

    Attributes
    ----------
    cycle : int
        The n whose n-differences were measured [forcing periods] (0: none could be).
    jitter : float64[4] or float64[5]
        Jitter of one section per normalised component ``(y, ydot, theta,
        thetadot)`` [~rad], and of the swing's envelope [rad] where it was judged.
    repeats : bool
        Whether the record repeats after ``cycle`` periods within its noise:
        the jitter looks like noise (small, no drift, not smooth) and every
        n-difference is within ``tolerance``.
    tolerance : float64 like ``jitter``
        The tolerance per component the jitter sets [~rad]: :data:`NOISE_SIGMAS`
        jitters plus the channel's finest step, never below :data:`PERIODIC_TOL`.
    step : float64 like ``jitter``
        The finest nonzero n-difference per component [~rad]: a quantised
        channel's step (the encoder's), far below the jitter for a continuous one.
    """

    cycle: int
    jitter: np.ndarray
    repeats: bool
    tolerance: np.ndarray
    step: np.ndarray

    @property
    def largest_jitter(self) -> float:
        return float(np.max(self.jitter))

    @property
    def applied_tolerance(self) -> float:
        """The largest tolerance a repeat was judged with [~rad]: :data:`PERIODIC_TOL` unless it repeats within noise."""
        return float(np.max(self.tolerance)) if self.repeats else PERIODIC_TOL


def section_scales(records: np.ndarray, params: ModelParams) -> np.ndarray:
    """Divisors ``(Y, w_e Y, 1, w_p)`` that make the section dimensionless.

    ``Y`` is the largest |y| of the record, at least :data:`Y_FLOOR` (1 when
    the record holds no finite value).
    """
    y = records[:, REC_Y_ABSMAX]
    Y = max(float(np.nanmax(y)), Y_FLOOR) if np.isfinite(y).any() else 1.0
    return np.array([Y, params.omega_e * Y, 1.0, params.omega_p])


def section_difference(a: np.ndarray, b: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """Normalised ``a - b`` of section states (last axis of length >= 4), theta wrapped."""
    d = (np.asarray(a)[..., :4] - np.asarray(b)[..., :4]) / scales
    d[..., _THETA] = wrapped(d[..., _THETA])
    return d


def wrapped(theta: np.ndarray) -> np.ndarray:
    """Angles [rad] wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * theta))


def section_period(sections: np.ndarray, scales: np.ndarray, tol: float = PERIODIC_TOL) -> int:
    """Smallest n <= MAX_PERIOD with the section repeating after n periods (0: none).

    ``sections`` is ``(n_periods, 4)``; at least two repeats of the n-cycle
    are required.
    """
    return int(section_periods(sections[None], np.asarray(scales)[None], tol)[0])


def section_periods(sections: np.ndarray, scales: np.ndarray, tol: float = PERIODIC_TOL) -> np.ndarray:
    """:func:`section_period` of many equally long section records at once.

    Parameters
    ----------
    sections : float64[k, n_periods, >= 4]
        Section states ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])`` per record.
    scales : float64[k, 4]
        Their normalisations (:func:`section_scales`).
    tol : float
        Largest normalised mismatch of a repeat [~rad].

    Returns
    -------
    int64[k]
        Smallest repeating n <= :data:`MAX_PERIOD` per record (0: none).
    """
    k, n_periods = sections.shape[:2]
    period = np.zeros(k, dtype=np.int64)
    divisors = np.asarray(scales, dtype=np.float64)[:, None, :]
    for n in range(1, MAX_PERIOD + 1):
        if n_periods < 2 * n + 1:
            break
        mismatch = np.abs(section_difference(sections[:, n:], sections[:, :-n], divisors)).max(axis=(1, 2))
        period[(period == 0) & (mismatch < tol)] = n
    return period


def cycle_noise(
    sections: np.ndarray, scales: np.ndarray, n: int, envelope: np.ndarray | None = None
) -> SectionNoise | None:
    """The jitter of a record's n-differences, and whether it repeats after n periods within it.

    Parameters
    ----------
    sections : float64[n_periods, >= 4]
        Finite section states ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])``.
    scales : float64[4]
        Their normalisation (:func:`section_scales`).
    n : int
        The cycle [forcing periods].
    envelope : float64[n_periods] or None
        Each period's largest |theta| [rad] (record column ``theta_absmax``),
        judged as a fifth component: a swing that decays or grows drifts there
        even where the section, sampled near a zero crossing, hides it.

    Returns
    -------
    SectionNoise or None
        None when the record leaves fewer than :data:`NOISE_MIN_PAIRS` lag-n
        pairs of n-differences (module docstring, "Noisy records").
    """
    if sections.shape[0] - 2 * n < NOISE_MIN_PAIRS:
        return None
    d = section_difference(sections[n:, :4], sections[:-n, :4], scales)
    if envelope is not None:
        d = np.column_stack([d, envelope[n:] - envelope[:-n]])
    jitter = np.sqrt(np.mean(d**2, axis=0) / 2.0)  # d = e(k+n) - e(k): twice one section's variance
    # A quantised channel (the encoder) differs by a whole step between two readings of one value:
    # its finest step joins the tolerance (for a continuous channel it is far below the jitter).
    magnitude = np.abs(d)
    finest = np.where(magnitude > 0, magnitude, np.inf).min(axis=0)
    step = np.where(np.isfinite(finest), finest, 0.0)
    tolerance = np.maximum(PERIODIC_TOL, NOISE_SIGMAS * jitter + step)
    # Only components that fail the noise-free rule need noise to explain them: one that repeats to
    # PERIODIC_TOL, or a quantised one that flickers by a step or two, is judged no further (a 3e-5 ringing
    # of y or an envelope wandering by an encoder step is no drift of the orbit).
    judged = magnitude.max(axis=0) > np.maximum(PERIODIC_TOL, 2.0 * step)
    d_judged = d[:, judged]
    no_drift = np.all(
        np.abs(d_judged.mean(axis=0)) <= NOISE_DRIFT_SIGMAS * d_judged.std(axis=0, ddof=1) / math.sqrt(d.shape[0])
    )
    noise_like = jitter.max() <= NOISE_MAX and bool(no_drift) and not _smooth(d_judged, n)
    return SectionNoise(n, jitter, bool(noise_like and np.all(magnitude < tolerance)), tolerance, step)


def _smooth(d: np.ndarray, n: int) -> bool:
    """Whether some component of the n-differences ``d`` (m, c) moves smoothly rather than jitters.

    Its autocorrelation averaged over lags 1..n reaches :data:`NOISE_SMOOTHNESS`:
    for independent jitter it is -1/(2n) (0 at lags below n, -1/2 at n, where
    consecutive differences share a section of opposite sign); for a drift, a
    decaying swing or a torus's slow rotation it is near +1.
    """
    power = np.sum(d**2, axis=0)
    lags = np.array([np.sum(d[:-lag] * d[lag:], axis=0) for lag in range(1, n + 1)])
    correlation = lags.mean(axis=0) / np.where(power > 0, power, np.inf)
    return bool(np.any(correlation >= NOISE_SMOOTHNESS))


def measured_noise(sections: np.ndarray, scales: np.ndarray, envelope: np.ndarray | None = None) -> SectionNoise:
    """A record's own section noise (module docstring, "Noisy records").

    Every measurable cycle n gets its :func:`cycle_noise` (with the swing's
    ``envelope`` [rad] when given); its level is its largest component's
    jitter, each component counted at least at its finest step over the
    record (a quantised channel's resolution). The smallest level over the
    cycles is the record's noise floor, and the record's cycle is the
    smallest n whose level is within :data:`NOISE_FLOOR_RATIO` of it: a shorter
    cycle's larger jitter is motion (a period-4 orbit's two halves), not
    noise. The result is that cycle's noise; its ``repeats`` says whether
    the record repeats within it. A cycle at the floor that drifts or moves
    smoothly makes the record undecided (a transient), whatever longer
    cycles, with fewer differences to judge, might pass. With no cycle
    measurable, or a value not finite: NaN jitter, the tolerance
    :data:`PERIODIC_TOL`.
    """
    sections = np.asarray(sections, dtype=np.float64)
    width = 4 if envelope is None else 5
    cycles = []
    if np.isfinite(sections[:, :4]).all() and (envelope is None or np.isfinite(envelope).all()):
        cycles = [c for n in range(1, MAX_PERIOD + 1) if (c := cycle_noise(sections, scales, n, envelope)) is not None]
    if not cycles:
        return SectionNoise(0, np.full(width, math.nan), False, np.full(width, PERIODIC_TOL), np.zeros(width))
    # A quantised channel's jitter is known only to its step (a few encoder flickers more or less):
    # each component counts at least its finest step over the record.
    step = np.min([c.step for c in cycles], axis=0)
    levels = [float(np.max(np.maximum(c.jitter, step))) for c in cycles]
    floor = min(levels)
    return next(c for c, level in zip(cycles, levels) if level <= NOISE_FLOOR_RATIO * floor)


def noisy_section_period(sections: np.ndarray, scales: np.ndarray, noise: SectionNoise) -> int:
    """Smallest n with the section repeating to :data:`PERIODIC_TOL` or, on a noisy record, within its ``noise``."""
    plain = section_period(sections, scales)
    within_noise = noise.cycle if noise.repeats else 0
    return min(n for n in (plain, within_noise) if n) if plain or within_noise else 0
