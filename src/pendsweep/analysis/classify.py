"""Motion classification of a sweep point from its recorded periods.

Every sweep unit (direction, point, start) gets one ``motion`` label:

``semi-trivial``
    At rest: max |theta| over the record below ``rest_threshold`` (one
    encoder pulse, 0.0013 rad, by default; :func:`at_rest`).
``periodic-n`` (n = 1..8)
    The stroboscopic section repeats after n forcing periods: every
    component of the normalised section differs from the one n periods
    earlier by less than :data:`PERIODIC_TOL`, or, on a backend whose
    records carry noise, by less than the tolerance the record's own
    measured noise sets (below, "Noisy records"). The smallest such n is
    given; the pendulum's subharmonic swing at fe/2 is ``periodic-2``.
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

The normalised section and its repeats are :mod:`pendsweep.analysis.sections`'.

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

Noisy records (backends with ``noisy`` True: a rig's sensors, the
substructured loop's load cell, encoder and LVDT) repeat within their own
measured noise (:mod:`pendsweep.analysis.sections`, "Noisy records"); a noisy record
whose last period is at rest is still coming to rest (``transient``) even
if it repeats within noise. Result rows of such backends carry
``section_noise`` and ``periodic_tol``; the same test decides whether an
extension's tail repeats.

Staged evidence (:func:`classify_runs`' default): a record with rotations
gets the Lyapunov pair alone (it is ``rotating`` or ``chaotic``, which
only the exponent tells apart). A swinging record is extended in rounds of
:data:`EXTEND_ROUND` periods, up to :data:`EXTEND_PERIODS`. After each
round, a point whose last :data:`TAIL_PERIODS` extension sections repeat
(:func:`section_period`) stops and is ``transient``, without a Lyapunov
pair. Only extensions that never repeat get the pair. ``evidence="full"``
runs the whole extension and the pair for every undecided point, and so
does every backend but the batched emulated one (its rounds continue a run
exactly; a backend with sensor noise would replay its noise sequence in
every round). The two differ only on a chaotic transient that settles within the extension:
full calls it ``chaotic`` (from the record's exponent), staged calls it
``transient``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..backends import PointRun
from ..backends.status import Status
from ..kernels._batched import twin_separation
from ..kernels._layout import REC_ROTATIONS, REC_THETA_ABSMAX, REC_THETADOT_SEC, REC_Y_SEC
from ..model.params import ENCODER_RESOLUTION, ModelParams
from .sections import (
    MAX_PERIOD,
    SectionNoise,
    measured_noise,
    noisy_section_period,
    section_period,
    section_periods,
    section_scales,
    wrapped,
)

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
#: Staged evidence: the extension runs in rounds of this many periods, and a
#: point stops after the round in which its section repeats [forcing periods].
EXTEND_ROUND = 25
#: Sections at the end of an extension tested for a late repeat [forcing periods].
TAIL_PERIODS = 4 * MAX_PERIOD
#: How much evidence :func:`classify_runs` gathers (module docstring, "Staged evidence").
EVIDENCE_MODES = ("staged", "full")
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
        (NaN when not needed: semi-trivial and periodic points, and those
        whose staged extension repeats).
    extension_periods : int
        Periods simulated past the record for this label [forcing periods].
    lyapunov_pair : bool
        Whether the two-trajectory Lyapunov pair was run for this label.
    noise : SectionNoise or None
        The record's measured noise and the tolerance it set (noisy backends
        only, module docstring "Noisy records").
    """

    label: str
    period: int = 0
    lyapunov: float = math.nan
    lyapunov_err: float = math.nan
    extension_periods: int = 0
    lyapunov_pair: bool = False
    noise: SectionNoise | None = None


@dataclass(frozen=True)
class Evidence:
    """What the extended record adds: sections ``(m, 4)`` and Lyapunov samples ``(k,)``."""

    sections: np.ndarray
    log_stretch: np.ndarray


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
    u[:, _THETA] = wrapped(u[:, _THETA])
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
    records: np.ndarray,
    scales: np.ndarray,
    status: Status = Status.OK,
    rest_threshold: float = ENCODER_RESOLUTION,
    period: int | None = None,
    noise: SectionNoise | None = None,
) -> Motion | None:
    """The label when the record alone decides it, else None (the point needs :class:`Evidence`).

    ``rest_threshold`` [rad] is the run's "at rest" limit (:func:`at_rest`);
    ``period`` is the record's :func:`section_period` when already computed
    (:func:`classify_runs` computes many at once); ``noise`` the record's
    :func:`measured_noise` on a noisy backend (its tolerance decides a repeat).
    """
    if status is not Status.OK or not np.isfinite(records).all():
        return Motion("n/a")
    if at_rest(records[:, REC_THETA_ABSMAX], rest_threshold):
        return Motion("semi-trivial")
    if noise is not None and at_rest(records[-1, REC_THETA_ABSMAX], rest_threshold):
        return Motion("transient")  # still coming to rest: a repeat within noise is no orbit yet
    if period is None:
        sections = records[:, _SEC]
        period = section_period(sections, scales) if noise is None else noisy_section_period(sections, scales, noise)
    if period:
        return Motion("rotating" if np.any(records[:, REC_ROTATIONS] != 0) else f"periodic-{period}", period)
    if at_rest(records[-1, REC_THETA_ABSMAX], rest_threshold):
        return Motion("transient")  # still coming to rest
    return None


def classify_with_evidence(records: np.ndarray, scales: np.ndarray, ev: Evidence, noisy: bool = False) -> Motion:
    """The label of an undecided record (:func:`decided_by_record` gave None) from its evidence.

    ``noisy``: the backend's records carry noise, so whether the extension's
    tail repeats is decided with the tail's own :func:`measured_noise`.
    """
    lle, err = lyapunov_estimate(ev.log_stretch)
    if lle > LYAP_SIGMAS * err and lle > LYAP_FLOOR:
        return Motion("chaotic", 0, lle, err)
    if np.any(records[:, REC_ROTATIONS] != 0):
        return Motion("rotating", 0, lle, err)
    tail = ev.sections[-TAIL_PERIODS:]
    settles = (
        noisy_section_period(tail, scales, measured_noise(tail, scales)) if noisy else section_period(tail, scales)
    )
    if settles or (lle < -LYAP_SIGMAS * err and lle < -LYAP_FLOOR):
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
    noisy: bool = False,
) -> Motion:
    """Classify one unit from its per-period records (``pendsweep.kernels.RECORD_COLUMNS``).

    ``evidence`` is called only when the record itself is not decisive
    (not at rest, not periodic); without it such points are ``transient``.
    ``rest_threshold`` [rad] is the run's "at rest" limit (:func:`at_rest`).
    ``noisy``: the records carry noise; periodicity is judged with the
    tolerance of their :func:`measured_noise` (module docstring, "Noisy records").
    """
    noise = measured_noise(records[:, _SEC], scales, records[:, REC_THETA_ABSMAX]) if noisy else None
    motion = decided_by_record(records, scales, status, rest_threshold, noise=noise)
    if motion is None:
        motion = Motion("transient") if evidence is None else classify_with_evidence(records, scales, evidence(), noisy)
    return replace(motion, noise=noise)


def backend_evidence(
    backend,
    params: ModelParams,
    run: PointRun,
    scales: np.ndarray,
    rest_threshold: float = ENCODER_RESOLUTION,
    extend_periods: int = EXTEND_PERIODS,
) -> Evidence:
    """Extend the record by ``extend_periods`` (0: no extension) and estimate the Lyapunov exponent, point by point."""
    sections = np.empty((0, 4))
    if extend_periods:
        extension = backend.run_point(params, run.state, 0, extend_periods)
        if extension.status is Status.OK:
            sections = extension.records[:, _SEC]

    def advance(state: np.ndarray) -> tuple[np.ndarray, float]:
        one = backend.run_point(params, state, 0, 1)
        return one.state, float(one.records[0, REC_THETA_ABSMAX])

    start = backend.initial_state(params, *run.records[0, _SEC])
    periods = max(run.records.shape[0], LYAP_MIN_PERIODS)
    return Evidence(
        sections, two_trajectory_log_stretch(advance, start, periods, scales, rest_threshold=rest_threshold)
    )


def gather_evidence(
    backend,
    params: Sequence[ModelParams],
    runs: Sequence[PointRun],
    scales: Sequence[np.ndarray],
    rest_threshold: float = ENCODER_RESOLUTION,
    extend_periods: int = EXTEND_PERIODS,
) -> list[Evidence]:
    """The :class:`Evidence` of many points: an ``extend_periods`` extension (0: none) and a Lyapunov pair each.

    A batched backend (``backend.batched``) integrates every point's
    extension and Lyapunov twin in one launch (its ``evidence_many``);
    others re-simulate point by point through :func:`backend_evidence`.
    ``rest_threshold`` [rad] is the run's "at rest" limit (:func:`at_rest`).
    """
    if not runs:
        return []
    if not backend.batched:
        return [
            backend_evidence(backend, q, r, s, rest_threshold, extend_periods) for q, r, s in zip(params, runs, scales)
        ]
    found = backend.evidence_many(
        list(params),
        np.array([r.state[:4] for r in runs]),
        np.array([r.records[0, _SEC] for r in runs]),
        np.array(scales),
        extend_periods=extend_periods,
        lyapunov_periods=max(runs[0].records.shape[0], LYAP_MIN_PERIODS),
        d0=LYAP_D0,
        rest=rest_threshold,
    )
    return [Evidence(sections, stretch) for sections, stretch in found]


def staged_extension(
    backend, params: Sequence[ModelParams], runs: Sequence[PointRun], scales: Sequence[np.ndarray]
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Extend records in rounds of :data:`EXTEND_ROUND` periods, each until its section repeats.

    After every round a point whose last :data:`TAIL_PERIODS` extension
    sections repeat (:func:`section_period`, the classifier's own test and
    tolerance) stops; the others go on, up to :data:`EXTEND_PERIODS`, so an
    extension that never repeats is the full one, period for period.

    Returns
    -------
    sections : list of float64[m, 4]
        Each point's extension sections (empty when the extension diverged,
        as in :func:`gather_evidence`).
    repeated : bool[k]
        Whether the section repeated within :data:`EXTEND_PERIODS`.
    periods : int64[k]
        Extension periods integrated per point [forcing periods].
    """
    k = len(runs)
    pieces: list[list[np.ndarray]] = [[] for _ in range(k)]
    states = [r.state for r in runs]
    repeated = np.zeros(k, dtype=bool)
    periods = np.zeros(k, dtype=np.int64)
    divisors = np.array(scales, dtype=np.float64).reshape(k, 4)
    active = np.arange(k)
    done = 0
    while active.size and done < EXTEND_PERIODS:
        length = min(EXTEND_ROUND, EXTEND_PERIODS - done)
        rounds = backend.run_points([params[j] for j in active], np.array([states[j] for j in active]), 0, length)
        done += length
        periods[active] = done
        going = []
        for j, extension in zip(active, rounds):
            if extension.status is Status.OK:
                pieces[j].append(extension.records[:, _SEC])
                states[j] = extension.state
                going.append(j)
            else:
                pieces[j] = []  # a diverged extension shows nothing (as a full one that diverges)
        active = np.array(going, dtype=np.int64)
        if active.size:  # every active extension is ``done`` periods long: one array
            tails = np.stack([np.concatenate(pieces[j])[-TAIL_PERIODS:] for j in active])
            repeats = section_periods(tails, divisors[active]) > 0
            repeated[active[repeats]] = True
            active = active[~repeats]
    sections = [np.concatenate(p) if p else np.empty((0, 4)) for p in pieces]
    return sections, repeated, periods


def _section_periods_of(
    runs: Sequence[PointRun], scales: list[np.ndarray], noises: dict[int, SectionNoise]
) -> dict[int, int]:
    """:func:`section_period` of every finite record, by index, computed together per record length.

    A record with a measured noise (``noises``, noisy backends) may repeat within it (:func:`noisy_section_period`).
    """
    by_length: dict[int, list[int]] = {}
    for j, r in enumerate(runs):
        if r.status is Status.OK and np.isfinite(r.records).all():
            by_length.setdefault(r.records.shape[0], []).append(j)
    periods: dict[int, int] = {}
    for group in by_length.values():
        found = section_periods(
            np.stack([runs[j].records[:, _SEC] for j in group]), np.stack([scales[j] for j in group])
        )
        periods.update(zip(group, found.tolist()))
    for j, noise in noises.items():
        if j in periods and noise.repeats:
            periods[j] = min(n for n in (periods[j], noise.cycle) if n)
    return periods


def classify_runs(
    backend,
    params: Sequence[ModelParams],
    runs: Sequence[PointRun],
    rest_threshold: float = ENCODER_RESOLUTION,
    evidence: str = "staged",
) -> list[Motion]:
    """Classify finished points; the evidence of all undecided ones is computed together.

    Parameters
    ----------
    backend
        The points' backend; evidence is re-simulated with it
        (:func:`gather_evidence`, :func:`staged_extension`).
    params, runs : sequences of the same length
        The points' parameters and finished runs.
    rest_threshold : float
        The run's "at rest" limit [rad] (:func:`at_rest`).
    evidence : {"staged", "full"}
        ``full``: every undecided point gets the whole :data:`EXTEND_PERIODS`
        extension and a Lyapunov pair. ``staged`` (module docstring): a
        record with rotations gets the Lyapunov pair alone, a swinging one
        an extension in rounds that stops once its section repeats
        (``transient``), and only points whose extension never repeats get
        the pair.

    Returns
    -------
    list of Motion
        With ``extension_periods`` and ``lyapunov_pair`` telling the evidence each point
        needed, and on a noisy backend (``backend.noisy``) the record's measured ``noise``.
    """
    if evidence not in EVIDENCE_MODES:
        raise ValueError(f"evidence = {evidence!r}; choose one of {', '.join(EVIDENCE_MODES)}")
    scales = [section_scales(r.records, q) if r.status is Status.OK else np.ones(4) for q, r in zip(params, runs)]
    noisy = bool(backend.noisy)
    noises = {
        j: measured_noise(r.records[:, _SEC], s, r.records[:, REC_THETA_ABSMAX])
        for j, (r, s) in enumerate(zip(runs, scales))
        if noisy and r.status is Status.OK
    }
    motions = _labelled(backend, params, runs, scales, noises, rest_threshold, evidence, noisy)
    return [replace(m, noise=noises.get(j)) for j, m in enumerate(motions)] if noisy else motions


def _labelled(backend, params, runs, scales, noises, rest_threshold, evidence, noisy) -> list[Motion]:
    """The labels of :func:`classify_runs` (``noises``: measured per finished record when ``noisy``)."""
    periods = _section_periods_of(runs, scales, noises)
    motions = [
        decided_by_record(r.records, s, r.status, rest_threshold, periods.get(j), noises.get(j))
        for j, (r, s) in enumerate(zip(runs, scales))
    ]
    undecided = [j for j, m in enumerate(motions) if m is None]
    if not undecided:
        return motions
    if not backend.restartable:  # it cannot be re-run from a state: no evidence beyond the record
        return [Motion("transient") if m is None else m for m in motions]
    # Staged rounds continue a run from its last state; a backend with sensor noise would restart its
    # noise sequence every round (the same 25-period noise over and over), so it gets the full evidence.
    if evidence == "full" or not backend.batched:
        found = gather_evidence(
            backend, [params[j] for j in undecided], [runs[j] for j in undecided], [scales[j] for j in undecided],
            rest_threshold,
        )  # fmt: skip
        for j, ev in zip(undecided, found):
            motion = classify_with_evidence(runs[j].records, scales[j], ev, noisy)
            motions[j] = replace(motion, extension_periods=EXTEND_PERIODS, lyapunov_pair=True)
        return motions
    # A record with rotations is rotating or chaotic, and only the Lyapunov pair tells which.
    swinging = [j for j in undecided if not np.any(runs[j].records[:, REC_ROTATIONS] != 0)]
    sections, repeated, periods = staged_extension(
        backend, [params[j] for j in swinging], [runs[j] for j in swinging], [scales[j] for j in swinging]
    )
    extension = {j: (s, int(n)) for j, s, n in zip(swinging, sections, periods)}
    for j, settles in zip(swinging, repeated):
        if settles:  # the record is a transient of an orbit that repeats
            motions[j] = Motion("transient", extension_periods=extension[j][1])
    pending = [j for j in undecided if motions[j] is None]
    found = gather_evidence(
        backend, [params[j] for j in pending], [runs[j] for j in pending], [scales[j] for j in pending],
        rest_threshold, extend_periods=0,
    )  # fmt: skip
    for j, ev in zip(pending, found):
        sections_j, periods_j = extension.get(j, (np.empty((0, 4)), 0))
        motion = classify_with_evidence(runs[j].records, scales[j], Evidence(sections_j, ev.log_stretch), noisy)
        motions[j] = replace(motion, extension_periods=periods_j, lyapunov_pair=True)
    return motions


def classify_run(
    backend, params: ModelParams, run: PointRun, rest_threshold: float = ENCODER_RESOLUTION, evidence: str = "staged"
) -> Motion:
    """Classify a finished sweep point, re-simulating with its backend when needed (see :func:`classify_runs`)."""
    return classify_runs(backend, [params], [run], rest_threshold, evidence)[0]
