"""Many emulated points at once: the batched kernel behind a small API.

:func:`run_batch` is the emulated backend's :meth:`run_points`, which sweeps
(``fresh`` and ``multistart`` modes) and Hopf simulation scans call for
independent points; :func:`batched_evidence` its ``evidence_many``, which
the motion classifier calls.
It groups points with equal steps per forcing period into lockstep chunks
(so that they share the exact forcing table), packs the rest into mixed
chunks, and runs the chunks on all numba threads.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import NamedTuple

import numba as nb
import numpy as np

from ..errors import ConfigError
from ..kernels import N_RECORD_COLUMNS, STATUS_OK
from ..kernels._batched import LANE_GROUP, Lanes, batched_periods
from ..kernels._layout import SECTION_COLUMNS
from ..model.params import KERNEL_FIELDS, ModelParams
from ._base import steps_per_period
from .gpu import check_device, run_batch_cuda

#: Points integrated in lockstep by one thread (a chunk's working set stays in L1/L2).
DEFAULT_CHUNK = 128

# One batched launch at a time per process: each already uses every core, and
# numba's fallback threading layer (workqueue) aborts on concurrent launches
# (e.g. Hopf tasks on several local threads).
_LAUNCH = threading.Lock()


class BatchRun(NamedTuple):
    """Outcome of :func:`run_batch` for ``n`` points.

    Attributes
    ----------
    records : float64[n, record_periods, 8]
        Per-period records, columns :data:`pendsweep.kernels.RECORD_COLUMNS`
        (NaN after a divergence).
    states : float64[n, 4]
        Final ``(y, ydot, theta, thetadot)`` per point (theta wrapped).
    status : int64[n]
        Kernel status codes (:class:`pendsweep.backends.status.Status` values).
    periods_done : int64[n]
        Periods completed, transient included, before any divergence.
    """

    records: np.ndarray
    states: np.ndarray
    status: np.ndarray
    periods_done: np.ndarray


def chunk_bounds(steps: np.ndarray, chunk: int) -> np.ndarray:
    """Chunk boundaries over points sorted by ``steps``.

    Runs of equal ``steps`` at least half a chunk long are cut into uniform
    chunks of at most ``chunk`` points; shorter runs are packed together into
    mixed chunks. Returns int64 ``bounds`` with chunk ``c`` = ``bounds[c]:bounds[c+1]``.
    """
    n = len(steps)
    edges = np.flatnonzero(np.diff(steps)) + 1
    cuts = {0, n}
    mixed_start = None  # first point of the current stretch of short runs
    for a, b in zip(np.r_[0, edges], np.r_[edges, n]):
        if b - a >= max(1, chunk // 2):
            if mixed_start is not None:
                cuts.update(range(mixed_start, a, chunk))
                mixed_start = None
            cuts.update(range(a, b, chunk))
            cuts.add(b)
        elif mixed_start is None:
            mixed_start = a
    if mixed_start is not None:
        cuts.update(range(mixed_start, n, chunk))
    return np.array(sorted(cuts), dtype=np.int64)


class ParameterColumns(NamedTuple):
    """What the kernels need of each point's :class:`~pendsweep.model.params.ModelParams`, at one requested step.

    Attributes
    ----------
    kernel_params : float64[n, N_PARAMS]
        ``ModelParams.kernel_array()`` of each point.
    alpha, fe : float64[n]
        Forcing amplitude [N] and frequency [Hz].
    steps : int64[n]
        RK4 steps per forcing period at the requested step.
    dt : float
        The requested step [s] they were built for.
    """

    kernel_params: np.ndarray
    alpha: np.ndarray
    fe: np.ndarray
    steps: np.ndarray
    dt: float

    def take(self, index: np.ndarray) -> ParameterColumns:
        """The columns of the points ``index`` (repeats allowed)."""
        return ParameterColumns(
            self.kernel_params[index], self.alpha[index], self.fe[index], self.steps[index], self.dt
        )


def parameter_columns(params: Sequence[ModelParams] | ParameterColumns, dt: float) -> ParameterColumns:
    """Per-point kernel inputs at the requested step ``dt`` [s], built once per distinct parameter set.

    Basins pass one set hundreds of thousands of times a round, so sets are
    told apart by identity. Columns already built are returned as they are;
    built for another ``dt``, they raise :class:`ConfigError`.
    """
    if isinstance(params, ParameterColumns):
        if params.dt != dt:
            raise ConfigError(f"parameter columns built for dt = {params.dt!r} s, used with dt = {dt!r} s")
        return params
    slot: dict[int, int] = {}  # id of a parameter set -> its row in the table, in order of first appearance
    index = np.fromiter((slot.setdefault(id(q), len(slot)) for q in params), dtype=np.int64, count=len(params))
    _, first = np.unique(index, return_index=True)
    ordered = [params[i] for i in first]
    return ParameterColumns(
        np.array([q.kernel_array() for q in ordered]).reshape(len(ordered), len(KERNEL_FIELDS)),
        np.array([q.alpha for q in ordered], dtype=np.float64),
        np.array([q.fe for q in ordered], dtype=np.float64),
        np.array([steps_per_period(q.fe, dt) for q in ordered], dtype=np.int64),
        float(dt),
    ).take(index)


def run_batch(
    params: Sequence[ModelParams] | ParameterColumns,
    states: np.ndarray,
    transient_periods: int,
    record_periods: int,
    *,
    dt: float = 1e-3,
    signum: str = "step",
    chunk: int = DEFAULT_CHUNK,
    threads: int | None = None,
    device: str = "cpu",
    precision: str = "float64",
) -> BatchRun:
    """Integrate independent points of the emulated system, vectorised across points.

    Parameters
    ----------
    params : sequence of ModelParams, length n, or ParameterColumns
        One parameter set per point (any of them may differ, ``fe`` included),
        or their columns built by :func:`parameter_columns` at this ``dt``.
    states : array_like, shape (n, 4)
        Initial ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])``.
    transient_periods, record_periods : int
        Forcing periods discarded, then recorded.
    dt : float
        Requested step [s]; as in :class:`~pendsweep.backends.EmulatedBackend`
        each point uses ``1 / (fe * round(1 / (fe * dt)))``.
    signum : {"step", "stage"}
        Hold sgn(thetadot) over a step (the paper) or evaluate it per stage.
    chunk : int
        Points per lockstep chunk.
    threads : int, optional
        numba threads for this call (default: all; ignored on a GPU).
    device : {"cpu", "cuda"}
        Where to integrate: the CPU batched kernel, or one GPU thread per
        point (:func:`pendsweep.backends.gpu.run_batch_cuda`; raises ``ConfigError``
        when no CUDA GPU is usable).
    precision : {"float64", "float32"}
        Arithmetic on the GPU (float32 only with ``device="cuda"``; see docs/gpu.md).

    Returns
    -------
    BatchRun
        In the order of ``params``. Agrees with the scalar kernel to about
        1e-12 relative on periodic motion (tests check 1e-9).
    """
    columns = parameter_columns(params, dt)
    n = len(columns.steps)
    if signum not in ("step", "stage"):
        raise ConfigError(f"signum = {signum!r}; choose 'step' or 'stage'")
    for name, v, lo in (
        ("transient_periods", transient_periods, 0),
        ("record_periods", record_periods, 1),
        ("chunk", chunk, 1),
    ):
        if int(v) != v or v < lo:
            raise ConfigError(f"{name} = {v!r} must be an integer >= {lo}")
    check_device(device, precision)
    if device == "cuda" and n:
        return BatchRun(*run_batch_cuda(
            columns.kernel_params, columns.alpha, columns.fe, columns.steps, np.asarray(states, dtype=np.float64).reshape(n, 4),
            int(transient_periods), int(record_periods), sgn_per_stage=signum == "stage", precision=precision,
        ))  # fmt: skip
    lanes = Lanes(
        transient=np.full(n, int(transient_periods), dtype=np.int64),
        total=np.full(n, int(transient_periods) + int(record_periods), dtype=np.int64),
        partner=np.full(n, -1, dtype=np.int64),
        scales=np.ones((4, n)),
        d0=1.0,
        rest=0.0,
    )
    run, _ = run_lanes(columns, states, lanes, int(record_periods), dt=dt, signum=signum, chunk=chunk, threads=threads)
    return run


def run_lanes(
    params: Sequence[ModelParams] | ParameterColumns,
    states: np.ndarray,
    lanes: Lanes,
    record_periods: int,
    stretch_periods: int = 0,
    *,
    dt: float = 1e-3,
    signum: str = "step",
    chunk: int = DEFAULT_CHUNK,
    threads: int | None = None,
) -> tuple[BatchRun, np.ndarray]:
    """Integrate lanes with their own schedules (and twins) in one launch of the batched kernel.

    ``lanes`` is the kernel's :class:`~pendsweep.kernels._batched.Lanes` in the
    order of ``params`` (a twin's ``partner`` indexes that order); lanes are
    sorted by steps per period and length here and the indices remapped. Returns the :class:`BatchRun` (records ``(n, record_periods, 8)``) and the
    twins' log-stretch samples ``(n, stretch_periods)``, NaN where none, in
    the order of ``params``. A twin and its partner are kept in one chunk.
    Raises ``ValueError`` when a lane would record more than
    ``record_periods`` periods or a twin run longer than ``stretch_periods``.
    """
    kernel_params, alpha, fe, steps, _ = parameter_columns(params, dt)
    n = len(steps)
    total = np.asarray(lanes.total, dtype=np.int64)
    partner = np.asarray(lanes.partner, dtype=np.int64)
    if n and (total - np.asarray(lanes.transient)).max() > int(record_periods):
        raise ValueError(f"a lane records more than record_periods = {record_periods} periods")
    if (partner >= 0).any() and total[partner >= 0].max() > int(stretch_periods):
        raise ValueError(f"a twin runs more than stretch_periods = {stretch_periods} periods")
    states = np.asarray(states, dtype=np.float64).reshape(n, 4)
    records = np.full((n, int(record_periods), N_RECORD_COLUMNS), np.nan)
    stretch = np.full((n, int(stretch_periods)), np.nan)
    status = np.zeros(n, dtype=np.int64)
    done = np.zeros(n, dtype=np.int64)
    if n == 0:
        return BatchRun(records, states.copy(), status, done), stretch
    # Lanes sorted by steps per period (chunks share forcing tables), then by
    # length, so that a chunk's lanes finish together (its dead lanes are
    # still stepped until its longest one ends); each twin right after its partner.
    head = np.where(partner >= 0, partner, np.arange(n))
    order = np.lexsort((partner >= 0, head, total[head], steps))
    position = np.empty(n, dtype=np.int64)
    position[order] = np.arange(n)
    sorted_partner = np.where(partner[order] >= 0, position[np.maximum(partner[order], 0)], -1)
    lanes = lanes._replace(
        transient=np.ascontiguousarray(np.asarray(lanes.transient, dtype=np.int64)[order]),
        total=np.ascontiguousarray(np.asarray(lanes.total, dtype=np.int64)[order]),
        partner=np.ascontiguousarray(sorted_partner),
        scales=np.ascontiguousarray(np.asarray(lanes.scales, dtype=np.float64)[:, order]),
        d0=float(lanes.d0),
        rest=float(lanes.rest),
    )
    p = np.ascontiguousarray(kernel_params[order].T)
    alpha = np.ascontiguousarray(alpha[order])
    fe = np.ascontiguousarray(fe[order])
    sorted_steps = np.ascontiguousarray(steps[order])
    soa = np.ascontiguousarray(states[order].T)
    out = np.full_like(records, np.nan)
    out_stretch = np.full_like(stretch, np.nan)
    st = np.zeros(n, dtype=np.int64)
    dn = np.zeros(n, dtype=np.int64)
    with _LAUNCH:
        previous = nb.get_num_threads()
        wanted = max(1, min(int(threads or previous), nb.config.NUMBA_NUM_THREADS))
        # A small launch is still split over the threads, in whole vector groups
        # (each chunk is padded to one): 27 lanes on 2 threads run as 16 + 11, not 27.
        per_thread = -(-n // wanted)
        chunk = min(int(chunk), max(LANE_GROUP, -(-per_thread // LANE_GROUP) * LANE_GROUP))
        bounds = keep_twins_together(chunk_bounds(sorted_steps, chunk), sorted_partner)
        # No more threads than chunks: an idle thread only waits at the barrier.
        nb.set_num_threads(min(wanted, len(bounds) - 1))
        # Chunk costs differ (lanes finish or diverge early, steps differ): threads take
        # chunks one at a time instead of a fixed share each.
        previous_chunksize = nb.set_parallel_chunksize(1)
        try:
            batched_periods(soa, p, alpha, fe, sorted_steps, lanes, signum == "stage", bounds, out, st, dn, out_stretch)
        finally:
            nb.set_num_threads(previous)
            nb.set_parallel_chunksize(previous_chunksize)
    records[order] = out
    stretch[order] = out_stretch
    final = np.empty_like(states)
    final[order] = soa.T
    status[order] = st
    done[order] = dn
    return BatchRun(records, final, status, done), stretch


def keep_twins_together(bounds: np.ndarray, partner: np.ndarray) -> np.ndarray:
    """Chunk boundaries moved so that no cut falls between a twin and its partner just before it."""
    moved = [int(b) + 1 if 0 < b < len(partner) and partner[b] == b - 1 else int(b) for b in bounds]
    return np.array(sorted(set(moved)), dtype=np.int64)


def batched_evidence(
    params: Sequence[ModelParams],
    finals: np.ndarray,
    firsts: np.ndarray,
    scales: np.ndarray,
    *,
    extend_periods: int,
    lyapunov_periods: int,
    d0: float,
    rest: float,
    dt: float = 1e-3,
    signum: str = "step",
    threads: int | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The classifier's evidence for many points in one launch (see :mod:`pendsweep.analysis.classify`).

    Per point three lanes run in lockstep: the record extended by
    ``extend_periods`` from its final state (no lane when 0), and the two-trajectory Lyapunov
    pair from the first recorded section state (the twin displaced by
    ``d0 * scales[2]`` in theta), renormalised inside the kernel every period
    for ``lyapunov_periods``.

    Parameters
    ----------
    params : sequence of ModelParams, length m
    finals, firsts : float64[m, 4]
        Final states and first recorded section states of the points.
    scales : float64[m, 4]
        Section normalisation per point.

    Returns
    -------
    list of (sections float64[extend_periods or 0, 4], log_stretch float64[<= lyapunov_periods])
        Sections are empty when the extension diverged or ``extend_periods`` is 0.
    """
    m = len(params)
    firsts = np.asarray(firsts, dtype=np.float64).reshape(m, 4)
    twins = firsts.copy()
    twins[:, 2] += d0 * np.asarray(scales)[:, 2]
    # Per point: the extension (only when asked for; an idle lane would still
    # be stepped with its chunk), then the Lyapunov reference and its twin.
    per_point = 3 if extend_periods else 2
    starts = [np.asarray(finals, dtype=np.float64).reshape(m, 4)] if extend_periods else []
    states = np.stack([*starts, firsts, twins], axis=1).reshape(per_point * m, 4)
    role = np.tile(np.arange(3 - per_point, 3), m)  # 0 extension, 1 reference, 2 twin
    index = np.arange(per_point * m)
    total = np.where(role == 0, int(extend_periods), int(lyapunov_periods)).astype(np.int64)
    lanes = Lanes(
        transient=np.where(role == 0, 0, total),  # the Lyapunov pair records nothing, only its stretch
        total=total,
        partner=np.where(role == 2, index - 1, -1).astype(np.int64),
        scales=np.repeat(np.asarray(scales, dtype=np.float64).reshape(m, 4), per_point, axis=0).T,
        d0=float(d0),
        rest=float(rest),
    )
    lane_params = [q for q in params for _ in range(per_point)]
    run, stretch = run_lanes(
        lane_params, states, lanes, int(extend_periods), int(lyapunov_periods),
        dt=dt, signum=signum, threads=threads,
    )  # fmt: skip
    evidence = []
    for j in range(m):
        first = per_point * j
        ok = extend_periods and run.status[first] == STATUS_OK
        sections = run.records[first][:, SECTION_COLUMNS] if ok else np.empty((0, 4))
        samples = stretch[first + per_point - 1]
        stop = np.flatnonzero(np.isnan(samples))
        evidence.append((sections, samples[: stop[0]] if stop.size else samples))
    return evidence
