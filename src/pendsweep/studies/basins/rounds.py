"""Stroboscopic maps and the settling rounds: many starts integrated until each settles (:func:`settle_runs`)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from ...analysis.attractors import MATCH_TOL, ROTATION_WINDOW, SETTLE_TOL, SETTLE_WINDOW, section_scales_many, settling
from ...analysis.sections import MAX_PERIOD
from ...backends.status import Status
from ...kernels import N_RECORD_COLUMNS, STATUS_DIVERGED, STATUS_OK, STATUS_UNSTABLE
from ...kernels._layout import REC_THETA_ABSMAX, REC_THETADOT_SEC, REC_Y_SEC
from ...kernels._settle import carry_history, update_near_since
from ...model.params import ModelParams

if TYPE_CHECKING:  # pandas (0.3 s) is imported by the functions that build frames, not by importing this module
    pass


#: Forcing periods integrated between settling checks.
ROUND_PERIODS = 25
#: Starts per task (unit of persistence and of parallel work).
CHUNK_STARTS = 4096
#: Settling tolerance on backends with sensor noise and quantisation [normalised, ~rad]: about 8 encoder pulses.
NOISY_SETTLE_TOL = 0.01


def settle_tolerance(backend) -> float:
    """The settling tolerance for ``backend``'s records: :data:`NOISY_SETTLE_TOL` where they carry noise."""
    return NOISY_SETTLE_TOL if backend.noisy else SETTLE_TOL


#: Escape rate: fewest settling events in the fitted tail.
ESCAPE_MIN_EVENTS = 20

_SEC = slice(REC_Y_SEC, REC_THETADOT_SEC + 1)
_STATUS_CODE = {Status.OK: STATUS_OK, Status.DIVERGED: STATUS_DIVERGED, Status.UNSTABLE: STATUS_UNSTABLE}


class StroboscopicMap(Protocol):
    """What :func:`settle_runs` integrates (see the module docstring)."""

    def advance(self, states: np.ndarray, periods: int, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(records (k, periods, 8), final states (k, d), status codes (k,))`` from phase 0."""
        ...

    def scales_for(self, ids: np.ndarray, records: np.ndarray) -> np.ndarray:
        """Section divisors ``(k, 4)`` of runs ``ids`` from their records."""
        ...


@dataclass(frozen=True)
class EmulatedMap:
    """The emulated system as a stroboscopic map, on the batched kernel.

    Attributes
    ----------
    params : tuple of ModelParams
        One parameter set, or one per run (indexed by the run ids).
    dt : float
        Requested step [s] (see :class:`pendsweep.backends.EmulatedBackend`).
    signum : {"step", "stage"}
    threads : int, optional
        numba threads (default: all).
    device, precision : str
        ``"cpu"`` or ``"cuda"`` and the GPU's ``"float64"``/``"float32"``
        (see :func:`pendsweep.backends._batch.run_batch`).
    """

    params: tuple[ModelParams, ...]
    dt: float = 1e-3
    signum: str = "step"
    threads: int | None = None
    device: str = "cpu"
    precision: str = "float64"

    @functools.cached_property
    def _columns(self):
        """The kernel's parameter columns of ``params``, built once: a round indexes them instead of the sets."""
        from ...backends._batch import parameter_columns

        return parameter_columns(self.params, self.dt)

    def advance(self, states, periods, ids):
        from ...backends._batch import run_batch

        rows = np.zeros(len(ids), dtype=np.int64) if len(self.params) == 1 else np.asarray(ids, dtype=np.int64)
        run = run_batch(
            self._columns.take(rows), states, 0, periods, dt=self.dt, signum=self.signum, threads=self.threads,
            device=self.device, precision=self.precision,
        )  # fmt: skip
        return run.records, run.states, run.status

    @functools.cached_property
    def _frequencies(self) -> np.ndarray:
        """(omega_e, omega_p) [rad/s] of each parameter set, shape (len(params), 2)."""
        return np.array([(q.omega_e, q.omega_p) for q in self.params])

    def scales_for(self, ids: np.ndarray, records: np.ndarray) -> np.ndarray:
        if len(self.params) == 1:
            return section_scales_many(records, *self._frequencies[0])
        frequencies = self._frequencies[np.asarray(ids, dtype=np.int64)]
        return section_scales_many(records, frequencies[:, 0], frequencies[:, 1])


@dataclass(frozen=True)
class BackendMap:
    """Any registered backend as a stroboscopic map, one run at a time (threads across runs).

    Each run gets its own noise seed, ``SeedSequence([*entropy, run id])``,
    when the backend has a ``seed`` option, so runs see independent noise.
    """

    backend: Any
    params: ModelParams
    entropy: tuple[int, ...] = (0,)
    workers: int = 2

    def _backend_for(self, run_id: int):
        if not hasattr(self.backend, "seed"):
            return self.backend
        seed = int(np.random.SeedSequence([*self.entropy, int(run_id)]).generate_state(1)[0])
        return replace(self.backend, seed=seed)

    def advance(self, states, periods, ids):
        def one(i):
            run = self._backend_for(ids[i]).run_point(self.params, states[i], 0, periods)
            return run.records, run.state, _STATUS_CODE[run.status]

        with ThreadPoolExecutor(max(1, self.workers)) as pool:
            out = list(pool.map(one, range(len(ids))))
        if not out:
            return np.empty((0, periods, 8)), np.asarray(states), np.zeros(0, dtype=np.int64)
        return (
            np.stack([o[0] for o in out]),
            np.stack([o[1] for o in out]),
            np.array([o[2] for o in out], dtype=np.int64),
        )

    def scales_for(self, ids: np.ndarray, records: np.ndarray) -> np.ndarray:
        return section_scales_many(records, self.params.omega_e, self.params.omega_p)


@dataclass
class SettledRuns:
    """Per-run outcome of :func:`settle_runs` (arrays over ``k`` runs).

    Attributes
    ----------
    status : int64[k]
        Kernel status code (0 ok, 1 diverged, 2 unstable).
    settled : bool[k]
    period, turns : int64[k]
        Cycle length [forcing periods] and net rotations per cycle.
    at_rest : bool[k]
    settle_periods : int64[k]
        Forcing periods from the start to the first section of the settled
        stretch (repeating to ``SETTLE_TOL``); -1 when not settled.
    escape_periods : int64[k]
        Forcing periods from the start until the section stays within
        :data:`~pendsweep.analysis.attractors.MATCH_TOL` of repeating with the settled
        cycle: the end of the irregular (e.g. chaotic) transient, before the
        slow final convergence; -1 when not settled.
    periods_done : int64[k]
        Forcing periods integrated.
    cycle : float64[k, MAX_PERIOD, 4]
        The last ``period`` section points ``(y, ydot, theta, thetadot)``
        (NaN-padded; NaN when not settled).
    scales : float64[k, 4]
        Section divisors over the last window.
    theta_absmax : float64[k]
        max |theta| [rad] over the final window (the settled motion's swing).
    states : float64[k, d]
        Final states.
    """

    status: np.ndarray
    settled: np.ndarray
    period: np.ndarray
    turns: np.ndarray
    at_rest: np.ndarray
    settle_periods: np.ndarray
    escape_periods: np.ndarray
    periods_done: np.ndarray
    cycle: np.ndarray
    scales: np.ndarray
    theta_absmax: np.ndarray
    states: np.ndarray

    @property
    def motion(self) -> np.ndarray:
        """Motion class per run (``unsettled`` after the cap, ``n/a`` when it failed)."""
        from ...analysis.attractors import motion_label

        out = np.full(self.status.shape, "unsettled", dtype=object)
        out[self.status != 0] = "n/a"
        for i in np.flatnonzero(self.settled):
            out[i] = motion_label(bool(self.at_rest[i]), int(self.period[i]), int(self.turns[i]))
        return out


def settle_runs(
    system: StroboscopicMap,
    states: np.ndarray,
    max_periods: int,
    *,
    ids: np.ndarray | None = None,
    round_periods: int = ROUND_PERIODS,
    on_round: Callable[[int], None] | None = None,
    **settle_options: Any,
) -> SettledRuns:
    """Integrate runs in rounds until each has settled or reached ``max_periods``.

    Parameters
    ----------
    system : StroboscopicMap
    states : float64[k, d]
        Initial states at forcing phase 0.
    max_periods : int
        Cap on forcing periods per run; runs not settled by then are
        ``unsettled``.
    ids : int64[k], optional
        Run identifiers passed to ``system.advance`` (default ``0 .. k-1``).
    round_periods : int
        Forcing periods per round.
    on_round : callable, optional
        Called with the number of runs finished in each round (progress).
    **settle_options
        Passed to :func:`pendsweep.analysis.attractors.settling` (``tol``, ``window`` ...).

    Returns
    -------
    SettledRuns
    """
    states = np.array(states, dtype=np.float64, copy=True)
    k = states.shape[0]
    ids = np.arange(k, dtype=np.int64) if ids is None else np.asarray(ids, dtype=np.int64)
    window = settle_options.get("window", SETTLE_WINDOW)
    history_rows = max(
        window + settle_options.get("max_period", MAX_PERIOD), settle_options.get("rotation_window", ROTATION_WINDOW)
    )
    out = SettledRuns(
        status=np.zeros(k, dtype=np.int64),
        settled=np.zeros(k, dtype=bool),
        period=np.zeros(k, dtype=np.int64),
        turns=np.zeros(k, dtype=np.int64),
        at_rest=np.zeros(k, dtype=bool),
        settle_periods=np.full(k, -1, dtype=np.int64),
        escape_periods=np.full(k, -1, dtype=np.int64),
        periods_done=np.zeros(k, dtype=np.int64),
        cycle=np.full((k, MAX_PERIOD, 4), np.nan),
        scales=np.ones((k, 4)),
        theta_absmax=np.full(k, np.nan),
        states=states,
    )
    active = np.arange(k)
    # The buffer of a round (history, then the new records) lives in one of two stores, and the next round's
    # history is gathered into the other: a chunk of 1e5 starts (a GPU's) holds about 1 GB of buffer, and
    # allocating it anew every round cost more than the GPU's integration.
    capacity = k * min(history_rows + round_periods, max_periods) * N_RECORD_COLUMNS  # a buffer's rows at most
    stores = (np.empty(capacity), np.empty(capacity))
    current = 0  # the store holding this round's buffer

    def buffer_in(store: int, runs: int, rows: int) -> np.ndarray:
        return stores[store][: runs * rows * N_RECORD_COLUMNS].reshape(runs, rows, N_RECORD_COLUMNS)

    buffer = buffer_in(current, k, min(round_periods, max_periods))
    # near_since[i, n-1]: first period since which run i's section has stayed within MATCH_TOL
    # of repeating after n periods (updated every round, so no long history is kept).
    max_period = settle_options.get("max_period", MAX_PERIOD)
    near_since = np.zeros((k, max_period), dtype=np.int64)
    done = 0
    while active.size and done < max_periods:
        periods = min(round_periods, max_periods - done)
        records, new_states, status = system.advance(states[active], periods, ids[active])
        buffer[:, buffer.shape[1] - periods :] = records
        first_row = done + periods - buffer.shape[1]  # periods elapsed before the buffer's first row
        done += periods
        states[active] = new_states
        out.periods_done[active] = done
        scales = np.ascontiguousarray(system.scales_for(ids[active], buffer[:, -window:]))
        update_near_since(buffer, scales, periods, first_row, MATCH_TOL, near_since, active)
        found = settling(buffer, scales, **settle_options)
        failed = status != 0
        last = done >= max_periods
        finished = found.settled | failed | last
        f = np.flatnonzero(finished)
        idx = active[f]
        out.status[idx] = status[f]
        ok = found.settled[f] & ~failed[f]
        out.settled[idx] = ok
        out.period[idx] = np.where(ok, found.period[f], 0)
        out.turns[idx] = np.where(ok, found.turns[f], 0)
        out.at_rest[idx] = ok & found.at_rest[f]
        out.settle_periods[idx] = np.where(ok, first_row + found.onset[f] + 1, -1)
        near_onset = near_since[idx, np.maximum(found.period[f], 1) - 1] + 1
        near_onset = np.where(found.period[f] > 0, near_onset, out.settle_periods[idx])  # steady rotation: no cycle
        out.escape_periods[idx] = np.where(ok, np.minimum(near_onset, out.settle_periods[idx]), -1)
        out.scales[idx] = scales[f]
        out.theta_absmax[idx] = np.fmax.reduce(buffer[f, -window:, REC_THETA_ABSMAX], axis=1)
        cycle_length = np.maximum(found.period[f], 1)
        for n in np.unique(cycle_length[ok]):
            mine = ok & (cycle_length == n)
            out.cycle[idx[mine], :n] = buffer[f[mine], buffer.shape[1] - n :, _SEC]
        keep = np.flatnonzero(~finished)
        active = active[keep]
        held = min(history_rows, buffer.shape[1])  # the next round's history: the last rows of this buffer
        current = 1 - current
        following = buffer_in(current, keep.size, held + min(round_periods, max(max_periods - done, 0)))
        carry_history(buffer, keep, held, following)
        buffer = following
        if on_round is not None:
            on_round(int(f.size))
    return out
