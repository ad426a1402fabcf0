"""Many emulated points at once: the batched kernel behind a small API.

:func:`run_batch` is what sweeps (``fresh`` and ``multistart`` modes) and
Hopf simulation scans call for independent points on the emulated backend.
It groups points with equal steps per forcing period into lockstep chunks
(so that they share the exact forcing table), packs the rest into mixed
chunks, and runs the chunks on all numba threads.
"""

from __future__ import annotations

import threading
from typing import NamedTuple, Sequence

import numba as nb
import numpy as np

from .backends import steps_per_period
from .errors import ConfigError
from .kernels import N_RECORD_COLUMNS
from .kernels._batched import Lanes, batched_periods
from .params import ModelParams

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
        Kernel status codes (:class:`pendsweep.status.Status` values).
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


def run_batch(
    params: Sequence[ModelParams],
    states: np.ndarray,
    transient_periods: int,
    record_periods: int,
    *,
    dt: float = 1e-3,
    signum: str = "step",
    chunk: int = DEFAULT_CHUNK,
    threads: int | None = None,
) -> BatchRun:
    """Integrate independent points of the emulated system, vectorised across points.

    Parameters
    ----------
    params : sequence of ModelParams, length n
        One parameter set per point (any of them may differ, ``fe`` included).
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
        numba threads for this call (default: all).

    Returns
    -------
    BatchRun
        In the order of ``params``. Agrees with the scalar kernel to about
        1e-12 relative on periodic motion (tests check 1e-9).
    """
    n = len(params)
    states = np.asarray(states, dtype=np.float64).reshape(n, 4)
    if signum not in ("step", "stage"):
        raise ConfigError(f"signum = {signum!r}; choose 'step' or 'stage'")
    for name, v, lo in (("transient_periods", transient_periods, 0), ("record_periods", record_periods, 1), ("chunk", chunk, 1)):
        if int(v) != v or v < lo:
            raise ConfigError(f"{name} = {v!r} must be an integer >= {lo}")
    records = np.full((n, int(record_periods), N_RECORD_COLUMNS), np.nan)
    status = np.zeros(n, dtype=np.int64)
    done = np.zeros(n, dtype=np.int64)
    if n == 0:
        return BatchRun(records, states.copy(), status, done)
    steps = np.array([steps_per_period(q.fe, dt) for q in params], dtype=np.int64)
    order = np.argsort(steps, kind="stable")
    p = np.ascontiguousarray(np.stack([params[i].kernel_array() for i in order], axis=1))
    alpha = np.array([params[i].alpha for i in order])
    fe = np.array([params[i].fe for i in order])
    sorted_steps = np.ascontiguousarray(steps[order])
    soa = np.ascontiguousarray(states[order].T)
    out = np.full_like(records, np.nan)
    st = np.zeros(n, dtype=np.int64)
    dn = np.zeros(n, dtype=np.int64)
    bounds = chunk_bounds(sorted_steps, int(chunk))
    lanes = Lanes(
        transient=np.full(n, int(transient_periods), dtype=np.int64),
        total=np.full(n, int(transient_periods) + int(record_periods), dtype=np.int64),
        partner=np.full(n, -1, dtype=np.int64),
        scales=np.ones((4, n)),
        d0=1.0,
        rest=0.0,
    )
    with _LAUNCH:
        previous = nb.get_num_threads()
        # No more threads than chunks: an idle thread only waits at the barrier.
        nb.set_num_threads(max(1, min(int(threads or previous), nb.config.NUMBA_NUM_THREADS, len(bounds) - 1)))
        try:
            batched_periods(
                soa, p, alpha, fe, sorted_steps, lanes, signum == "stage", bounds, out, st, dn, np.empty((n, 0))
            )
        finally:
            nb.set_num_threads(previous)
    records[order] = out
    final = np.empty_like(states)
    final[order] = soa.T
    status[order] = st
    done[order] = dn
    return BatchRun(records, final, status, done)
