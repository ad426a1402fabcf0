"""Motion classification of a sweep point from its recorded periods.

Every sweep unit (direction, point, start) gets one ``motion`` label:

``semi-trivial``
    At rest: max |theta| over the record below ``rest_threshold`` (one
    encoder pulse, 0.0013 rad, by default; :func:`at_rest`).
``periodic-n`` (n = 1..8)
    The stroboscopic section repeats after n forcing periods: every
    component of the normalised section differs from the one n periods
    earlier by less than :data:`PERIODIC_TOL`. The smallest such n is given;
    the pendulum's subharmonic swing at fe/2 is ``periodic-2``.
``chaotic``
    The largest Lyapunov exponent is positive beyond its uncertainty:
    mean > :data:`LYAP_SIGMAS` standard errors and > :data:`LYAP_FLOOR`
    per forcing period (two-trajectory estimate, below).
``rotating``
    Net full rotations occur in the record and the motion is not chaotic
    (a periodic or quasi-periodic rotation; chaotic tumbling is ``chaotic``).
``quasi-periodic``
    Not periodic, Lyapunov exponent zero within its uncertainty, and the
    section points of an extended record (:data:`EXTEND_PERIODS` more
    periods) lie on closed curves: taking every n-th point (n = 1..8), the
    points sorted by angle about their centre surround it (no angular gap
    over :data:`CURVE_MAX_GAP`) and their radius varies smoothly (mean
    jump between neighbours below :data:`CURVE_ROUGHNESS` of the mean
    radius).
``transient``
    Not settled: the pendulum is still coming to rest (last recorded period
    at rest, earlier ones not), or the record is not
    periodic but the extended record becomes
    periodic, or the Lyapunov exponent is negative beyond its uncertainty
    (still converging to an orbit), or neither a closed curve nor chaos is
    found. Lengthen ``transient_periods`` to resolve such points.
``n/a``
    The point did not finish (status ``diverged`` or ``unstable``).

The normalised section is ``(y/Y, ydot/(w_e Y), theta, thetadot/w_p)`` with
``Y`` the largest |y| of the record, so all four components are
dimensionless and of the size of theta in rad; theta differences are
wrapped to (-pi, pi].

Lyapunov exponent: two trajectories, started from the first recorded
section state and a copy with theta moved by :data:`LYAP_D0`, are advanced
one forcing period at a time; after each period the log of the separation
growth (normalised section norm) is a sample and the copy is pulled back to
distance :data:`LYAP_D0` along the separation (Benettin). The estimate is
the mean over ``max(record, LYAP_MIN_PERIODS)`` periods [1/period]; its
standard error comes from means over blocks of :data:`LYAP_BLOCK` periods,
which absorbs the samples' short-range correlation. Backends with more
state than ``(y, ydot, theta, thetadot)`` restart their own states from
rest at the section, an approximation.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .backends import PointRun
from .kernels._batched import twin_separation
from .kernels._layout import REC_ROTATIONS, REC_THETA_ABSMAX, REC_THETADOT_SEC, REC_Y_ABSMAX, REC_Y_SEC
from .params import ENCODER_RESOLUTION, ModelParams
from .status import Status

#: Largest section mismatch [normalised, ~rad] still counted as a repeat.
PERIODIC_TOL = 1e-3
#: Longest period searched [forcing periods].
MAX_PERIOD = 8
#: Initial separation of the two trajectories [normalised, ~rad].
LYAP_D0 = 1e-8
#: Shortest window of the Lyapunov estimate [forcing periods].
LYAP_MIN_PERIODS = 60
#: Block length of the standard error [forcing periods].
LYAP_BLOCK = 5
#: "Positive beyond its uncertainty": this many standard errors ...
LYAP_SIGMAS = 3.0
#: ... and at least this rate [1/forcing period].
LYAP_FLOOR = 0.01
#: Periods simulated past the record to look for closed curves or late settling.
EXTEND_PERIODS = 200
#: Smallest oscillator amplitude a section is normalised by [m]: an unforced
#: oscillator decaying to rest would otherwise be measured against its own
#: vanishing amplitude and never repeat (1 nm is far below any displacement sensor).
Y_FLOOR = 1e-9
#: Closed-curve test: largest mean radius jump between angular neighbours [fraction of mean radius].
CURVE_ROUGHNESS = 0.1
#: Closed-curve test: largest angular gap between neighbours [rad].
CURVE_MAX_GAP = math.pi / 2

_SEC = slice(REC_Y_SEC, REC_THETADOT_SEC + 1)  # record columns y_sec, ydot_sec, theta_sec, thetadot_sec
_THETA = 2


def at_rest(theta_absmax: np.ndarray | float, rest_threshold: float = ENCODER_RESOLUTION) -> bool:
    """The one "pendulum at rest" rule: the largest |theta| [rad] of a window is below ``rest_threshold`` [rad].

    ``theta_absmax`` holds per-period envelopes (record column
    ``theta_absmax``) over the window in question; sweeps (kick in continue
    mode), the classifier and the Hopf protocol all decide rest here, with
    the run's ``rest_threshold`` (one encoder pulse by default). The batched
    evidence kernel applies the same comparison (its ``rest`` argument).
    """
    return float(np.max(theta_absmax)) < rest_threshold


@dataclass(frozen=True)
class Motion:
    """A classification and its evidence.

    Attributes
    ----------
    label : str
        One of the labels of the module docstring.
    period : int
        n of ``periodic-n`` (or of a periodic rotation), else 0.
    lyapunov, lyapunov_err : float
        Largest Lyapunov exponent and its standard error [1/forcing period]
        (NaN when not needed: semi-trivial and periodic points).
    """

    label: str
    period: int = 0
    lyapunov: float = math.nan
    lyapunov_err: float = math.nan


@dataclass(frozen=True)
class Evidence:
    """What the extended record adds: sections ``(m, 4)`` and Lyapunov samples ``(k,)``."""

    sections: np.ndarray
    log_stretch: np.ndarray


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
    d[..., _THETA] = _wrapped(d[..., _THETA])
    return d


def _wrapped(theta: np.ndarray) -> np.ndarray:
    """Angles [rad] wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * theta))


def section_period(sections: np.ndarray, scales: np.ndarray, tol: float = PERIODIC_TOL) -> int:
    """Smallest n <= MAX_PERIOD with the section repeating after n periods (0: none).

    ``sections`` is ``(n_periods, 4)``; at least two repeats of the n-cycle
    are required.
    """
    for n in range(1, MAX_PERIOD + 1):
        if sections.shape[0] < 2 * n + 1:
            break
        mismatch = np.abs(section_difference(sections[n:], sections[:-n], scales)).max()
        if mismatch < tol:
            return n
    return 0


def lyapunov_estimate(log_stretch: np.ndarray, block: int = LYAP_BLOCK) -> tuple[float, float]:
    """Mean [1/period] and block standard error of per-period log-stretch samples."""
    n_blocks = log_stretch.size // block
    if n_blocks < 2:
        return float(np.mean(log_stretch)), math.inf
    means = log_stretch[: n_blocks * block].reshape(n_blocks, block).mean(axis=1)
    return float(np.mean(log_stretch)), float(means.std(ddof=1) / math.sqrt(n_blocks))


def two_trajectory_log_stretch(
    advance: Callable[[np.ndarray], tuple[np.ndarray, float]],
    state: np.ndarray,
    periods: int,
    scales: np.ndarray,
    d0: float = LYAP_D0,
    rest_threshold: float = ENCODER_RESOLUTION,
) -> np.ndarray:
    """Per-period log separation growth of two nearby trajectories (Benettin).

    Parameters
    ----------
    advance : callable
        ``advance(state) -> (state one forcing period later, max |theta| [rad]
        during that period)``; the first four state entries are ``y, ydot,
        theta, thetadot``, later ones follow along.
    state : ndarray
        Start of the reference trajectory.
    periods : int
    scales : float64[4]
        Section normalisation (:func:`section_scales`).

    Returns
    -------
    float64[<= periods]
        ``log(|separation| / d0)`` after each period. The estimate stops
        early when the reference pendulum comes to rest (:func:`at_rest`
        with ``rest_threshold`` [rad]), where Coulomb friction chatters and the
        separation means nothing, or when a trajectory diverges.
    """
    reference = np.array(state, dtype=np.float64)
    copy = reference.copy()
    copy[_THETA] += d0 * scales[_THETA]
    out = []
    for _ in range(periods):
        (reference, swing), (copy, _) = advance(reference), advance(copy)
        full = copy - reference  # entries past the section follow along
        section, distance = twin_separation(tuple(reference[:4]), tuple(copy[:4]), scales)
        full[:4] = section
        if at_rest(swing, rest_threshold) or not (math.isfinite(distance) and distance > 0):
            break
        out.append(math.log(distance / d0))
        copy = reference + full * (d0 / distance)
    return np.array(out)


def closed_curve(sections: np.ndarray, scales: np.ndarray) -> bool:
    """Whether the section points lie on closed curves (every n-th point, some n <= 8)."""
    u = sections[:, :4] / scales
    u[:, _THETA] = _wrapped(u[:, _THETA])
    for n in range(1, MAX_PERIOD + 1):
        branch = u[::n]
        if branch.shape[0] < 12:
            break
        centred = branch - branch.mean(axis=0)
        # The curve's plane: its two principal directions.
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        plane = centred @ vt[:2].T
        angle = np.arctan2(plane[:, 1], plane[:, 0])
        order = np.argsort(angle)
        radius = np.hypot(plane[order, 0], plane[order, 1])
        gaps = np.diff(np.concatenate([angle[order], angle[order[:1]] + 2 * math.pi]))
        jumps = np.abs(np.diff(np.concatenate([radius, radius[:1]])))
        if gaps.max() < CURVE_MAX_GAP and jumps.mean() < CURVE_ROUGHNESS * radius.mean():
            return True
    return False


def decided_by_record(
    records: np.ndarray, scales: np.ndarray, status: Status = Status.OK, rest_threshold: float = ENCODER_RESOLUTION
) -> Motion | None:
    """The label when the record alone decides it, else None (the point needs :class:`Evidence`).

    ``rest_threshold`` [rad] is the run's "at rest" limit (:func:`at_rest`).
    """
    if status is not Status.OK or not np.isfinite(records).all():
        return Motion("n/a")
    if at_rest(records[:, REC_THETA_ABSMAX], rest_threshold):
        return Motion("semi-trivial")
    n = section_period(records[:, _SEC], scales)
    if n:
        return Motion("rotating" if np.any(records[:, REC_ROTATIONS] != 0) else f"periodic-{n}", n)
    if at_rest(records[-1, REC_THETA_ABSMAX], rest_threshold):
        return Motion("transient")  # still coming to rest
    return None


def classify_with_evidence(records: np.ndarray, scales: np.ndarray, ev: Evidence) -> Motion:
    """The label of an undecided record (:func:`decided_by_record` gave None) from its evidence."""
    lle, err = lyapunov_estimate(ev.log_stretch)
    if lle > LYAP_SIGMAS * err and lle > LYAP_FLOOR:
        return Motion("chaotic", 0, lle, err)
    if np.any(records[:, REC_ROTATIONS] != 0):
        return Motion("rotating", 0, lle, err)
    tail = ev.sections[-4 * MAX_PERIOD :]
    if section_period(tail, scales) or (lle < -LYAP_SIGMAS * err and lle < -LYAP_FLOOR):
        return Motion("transient", 0, lle, err)
    if closed_curve(ev.sections, scales):
        return Motion("quasi-periodic", 0, lle, err)
    return Motion("transient", 0, lle, err)


def classify_records(
    records: np.ndarray,
    scales: np.ndarray,
    status: Status = Status.OK,
    evidence: Callable[[], Evidence] | None = None,
    rest_threshold: float = ENCODER_RESOLUTION,
) -> Motion:
    """Classify one unit from its per-period records (``pendsweep.kernels.RECORD_COLUMNS``).

    ``evidence`` is called only when the record itself is not decisive
    (not at rest, not periodic); without it such points are ``transient``.
    ``rest_threshold`` [rad] is the run's "at rest" limit (:func:`at_rest`).
    """
    motion = decided_by_record(records, scales, status, rest_threshold)
    if motion is not None:
        return motion
    if evidence is None:
        return Motion("transient")  # undecidable here
    return classify_with_evidence(records, scales, evidence())


def backend_evidence(
    backend, params: ModelParams, run: PointRun, scales: np.ndarray, rest_threshold: float = ENCODER_RESOLUTION
) -> Evidence:
    """Extend the record and estimate the Lyapunov exponent with the point's backend."""
    extension = backend.run_point(params, run.state, 0, EXTEND_PERIODS)
    sections = extension.records[:, _SEC] if extension.status is Status.OK else np.empty((0, 4))

    def advance(state: np.ndarray) -> tuple[np.ndarray, float]:
        one = backend.run_point(params, state, 0, 1)
        return one.state, float(one.records[0, REC_THETA_ABSMAX])

    start = backend.initial_state(params, *run.records[0, _SEC])
    periods = max(run.records.shape[0], LYAP_MIN_PERIODS)
    return Evidence(
        sections, two_trajectory_log_stretch(advance, start, periods, scales, rest_threshold=rest_threshold)
    )


def classify_run(backend, params: ModelParams, run: PointRun, rest_threshold: float = ENCODER_RESOLUTION) -> Motion:
    """Classify a finished sweep point, re-simulating with its backend when needed."""
    return classify_runs(backend, [params], [run], rest_threshold)[0]


def classify_runs(
    backend, params: Sequence[ModelParams], runs: Sequence[PointRun], rest_threshold: float = ENCODER_RESOLUTION
) -> list[Motion]:
    """Classify finished points; the evidence of all undecided ones is computed together.

    A batched backend (``backend.batched``) integrates every undecided
    point's extension and Lyapunov twin in one launch (its
    ``evidence_many``); others re-simulate point by point through
    :func:`backend_evidence`. ``rest_threshold`` [rad] is the run's "at
    rest" limit (:func:`at_rest`), in both paths.
    """
    scales = [section_scales(r.records, q) if r.status is Status.OK else np.ones(4) for q, r in zip(params, runs)]
    motions = [decided_by_record(r.records, s, r.status, rest_threshold) for r, s in zip(runs, scales)]
    undecided = [j for j, m in enumerate(motions) if m is None]
    if not undecided:
        return motions
    if not backend.restartable:  # it cannot be re-run from a state: no evidence beyond the record
        return [Motion("transient") if m is None else m for m in motions]
    if backend.batched:
        found = backend.evidence_many(
            [params[j] for j in undecided],
            np.array([runs[j].state[:4] for j in undecided]),
            np.array([runs[j].records[0, _SEC] for j in undecided]),
            np.array([scales[j] for j in undecided]),
            extend_periods=EXTEND_PERIODS,
            lyapunov_periods=max(runs[undecided[0]].records.shape[0], LYAP_MIN_PERIODS),
            d0=LYAP_D0,
            rest=rest_threshold,
        )
        evidence = [Evidence(sections, stretch) for sections, stretch in found]
    else:
        evidence = [backend_evidence(backend, params[j], runs[j], scales[j], rest_threshold) for j in undecided]
    for j, ev in zip(undecided, evidence):
        motions[j] = classify_with_evidence(runs[j].records, scales[j], ev)
    return motions
