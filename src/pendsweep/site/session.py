"""A continuous hybrid test on a remote rig: one connection for a whole sweep branch (or both).

The paper's hybrid bifurcation diagram (Fig. 11(a1)) is measured by stepping
a parameter of the numerical model *while the test runs*: the specimen
cannot be put back into a chosen state between points. A :class:`RigSession`
is that test. It holds one connection to a site (:class:`~.client.RemoteRig`)
and the controller's whole state (numerical model, predictor history,
filter registers, command delay line) in the client, and runs any number of
forcing periods, point after point; between points only the numerical
model's parameters change, at a forcing-period boundary (forcing phase 0).

What a session can and cannot change
------------------------------------
* Numerical side (:data:`NUMERICAL_PARAMETERS`): the forcing ``alpha`` and
  ``fe``, the oscillator's ``M`` (so ``M1 = M - M2``), ``C`` (``C1``),
  ``K``, ``k3``. Physical side (:data:`PHYSICAL_PARAMETERS`: the pendulum
  and the platform) belongs to the site and cannot be swept from here.
* The controller runs at one step ``dt`` for the whole session (a site
  needs a constant step): the first point's. A forcing frequency is
  realised as ``1 / (n dt)`` with a whole number ``n`` of ticks per period
  (``fe_realised`` in the rows); its phase is continuous across a step
  since every period starts at phase 0.
* A ramp (``--ramp``) moves the swept parameter linearly, one step per
  forcing period, from the last point's value, for rigs that must not see a
  step (:meth:`pendsweep.sweep.SweepConfig.ramp_params`).

The safe stop (:meth:`RigSession.stop`): at the end of the forcing period
in progress (a limit or the instability monitor: at once), the forcing amplitude is ramped
to zero over ``stop_periods`` forcing periods (a step per period, at phase
0, so the force stays continuous), the numerical model left to decay with
its own damping for up to as many periods again, until its command is
within one LVDT step of rest, then the last step is committed and the site
told ``die``. A signal (SIGINT, SIGTERM), a limit (stroke, velocity, force
of :class:`~.rig.RigLimits`) or the instability monitor triggers it; a lost
or garbled reply cannot be ramped down (the rig is not answering) and
closes the connection at once.

The time series (:class:`TimeSeriesLog`) of every controller tick is kept
as the test runs, flushed in parts every few seconds (a killed client
loses at most that), and consolidated into one parquet file of kind
``trace`` that :func:`pendsweep.data.read_record` reads as a
``substructured`` record (``pendsweep diagnose``, ``pendsweep sync``).
"""

from __future__ import annotations

import math
import signal
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..errors import ConfigError, PendsweepError, RunFailure
from ..kernels import N_RECORD_COLUMNS
from ..kernels._emulated import forcing_table
from ..kernels._layout import STATUS_OK, STATUS_UNSTABLE
from ..kernels._records import TWO_PI, record_open
from ..kernels._site import client_tick
from ..kernels._substructured import (
    N_TRACE_COLUMNS,
    S_THETA,
    S_THETADOT,
    S_X,
    S_XDOT,
    S_Y,
    TRACE_COLUMNS,
    close_period,
    high_frequency_growth,
    stroke_status,
)
from ..params import KERNEL_FIELDS, ModelParams
from ..status import Status
from .client import RemoteRig, parse_rig_url
from .rig import RigLimits

#: Parameters of the numerical model, which the client integrates and a session may change between points.
NUMERICAL_PARAMETERS = ("alpha", "fe", "M", "C", "K", "k3")
#: Parameters of the physical substructure (pendulum and platform), which only the site can set.
PHYSICAL_PARAMETERS = (*(name for name in KERNEL_FIELDS if name not in NUMERICAL_PARAMETERS), "M2", "C2")
#: Default forcing periods of the safe stop's ramp to zero.
STOP_PERIODS = 5
#: Seconds between flushes of the time series (at most this much of it is lost when the client is killed).
TIMESERIES_FLUSH_SECONDS = 2.0
#: Exit status of a test stopped by SIGINT (the shell's 128 + 2); other stops exit 1.
SIGINT_STATUS = 130


class RigStopped(PendsweepError):
    """A continuous test that stopped before its end, safely (the rig ramped down) or not (the site went silent).

    ``exit_code`` is :data:`SIGINT_STATUS` after SIGINT, 1 otherwise.
    """

    def __init__(self, reason: str, exit_code: int = 1) -> None:
        super().__init__(reason)
        self.exit_code = exit_code


@dataclass
class StopRequest:
    """Why a running test must stop, set from a signal handler and read at every controller tick."""

    reason: str = ""
    exit_code: int = 1

    def __bool__(self) -> bool:
        return bool(self.reason)

    def set(self, reason: str, exit_code: int = 1) -> None:
        if not self.reason:  # the first cause is the one reported
            self.reason, self.exit_code = reason, exit_code


class stop_on_signals:
    """Context manager: SIGINT and SIGTERM set ``request`` instead of raising, so the rig can ramp down.

    Handlers can only be installed from the main thread; elsewhere (a worker)
    it does nothing and the caller's own handling applies.
    """

    def __init__(self, request: StopRequest) -> None:
        self.request = request
        self._old: dict[int, Any] = {}

    def __enter__(self) -> StopRequest:
        if threading.current_thread() is threading.main_thread():
            for sig, name, code in ((signal.SIGINT, "SIGINT", SIGINT_STATUS), (signal.SIGTERM, "SIGTERM", 1)):
                self._old[sig] = signal.signal(sig, lambda *_, n=name, c=code: self.request.set(f"stopped by {n}", c))
        return self.request

    def __exit__(self, *exc: Any) -> None:
        for sig, handler in self._old.items():
            signal.signal(sig, handler)


def check_sweepable(parameter: str, rig: str) -> None:
    """Refuse (``ConfigError``) a parameter that a client cannot change on a remote rig."""
    if parameter in PHYSICAL_PARAMETERS:
        raise ConfigError(
            f"{parameter} belongs to the physical substructure at {rig}, which the client cannot change; "
            f"sweep a parameter of the numerical model ({', '.join(NUMERICAL_PARAMETERS)}) or set it at the site"
        )
    if parameter not in NUMERICAL_PARAMETERS:
        raise ConfigError(f"{parameter} cannot be swept on a remote rig; accepted: {', '.join(NUMERICAL_PARAMETERS)}")


# -- the time series -------------------------------------------------------------------------------------------
class TimeSeriesLog:
    """Every controller tick of a test, written as it runs: parts flushed every few seconds, one file at the end.

    Parameters
    ----------
    path : Path
        The consolidated file (``...-timeseries.parquet``); parts live in
        ``path`` with suffix ``.parts`` until :meth:`consolidate`.
    metadata : dict
        The file's ``pendsweep`` metadata (kind ``trace``, see :mod:`pendsweep.logs`).
    parameter : str
        The swept parameter's column name.
    flush_seconds : float
        Longest time buffered rows wait for a write.

    Columns: :data:`~pendsweep.kernels._substructured.TRACE_COLUMNS` (the
    substructured trace's: ``t, Fe, y`` (y*), ``ydot, command, x, xdot,
    x_meas, theta, theta_true, thetadot, Fs, Fs_true, F_fb, sync_error``;
    the site's readings where the client has them, NaN where it has not),
    the parameter's value, ``round_trip`` [s], ``session`` and ``point``.
    """

    def __init__(self, path: Path, metadata: dict, parameter: str, flush_seconds: float = TIMESERIES_FLUSH_SECONDS):
        from ..results import schema_with_metadata

        self.path = Path(path)
        self.parts = self.path.with_name(self.path.name + ".parts")
        self.parts.mkdir(parents=True, exist_ok=True)
        self.parameter = parameter
        self.flush_seconds = flush_seconds
        names = [*TRACE_COLUMNS, parameter, "round_trip", "session", "point"]
        self.schema = schema_with_metadata(pa.schema([(n, pa.float64()) for n in names]), metadata)
        self._buffer: list[np.ndarray] = []
        self._last_flush = time.monotonic()
        self._next = 1 + max((int(p.stem) for p in self.parts.glob("*.parquet") if p.stem.isdigit()), default=-1)

    def sessions_so_far(self) -> int:
        """Sessions already in the parts (a resumed test's new session gets the next index)."""
        done = [pq.read_table(p, columns=["session"]) for p in sorted(self.parts.glob("*.parquet"))]
        return 1 + max((int(np.max(t["session"].to_numpy())) for t in done if t.num_rows), default=-1)

    def append(self, rows: np.ndarray) -> None:
        """Buffer ``rows`` (n, len(columns)); write a part when the last write is older than ``flush_seconds``."""
        self._buffer.append(rows)
        if time.monotonic() - self._last_flush >= self.flush_seconds:
            self.flush()

    def flush(self) -> None:
        """Write the buffered rows as one part, atomically (a killed client leaves whole parts only)."""
        from ..results import atomic_write_table

        self._last_flush = time.monotonic()
        if not self._buffer:
            return
        block = np.concatenate(self._buffer)
        self._buffer = []
        table = pa.Table.from_arrays([pa.array(block[:, j]) for j in range(block.shape[1])], schema=self.schema)
        atomic_write_table(table, self.parts / f"{self._next:06d}.parquet")
        self._next += 1

    def consolidate(self) -> Path:
        """Flush, then merge every part (this session's and earlier ones') into ``path``; the parts go."""
        from ..results import atomic_write_table

        self.flush()
        parts = sorted(self.parts.glob("*.parquet"))
        tables = [pq.read_table(p).cast(self.schema) for p in parts]
        atomic_write_table(pa.concat_tables(tables) if tables else self.schema.empty_table(), self.path)
        for p in parts:
            p.unlink()
        self.parts.rmdir()
        return self.path


def timeseries_path(output: Path) -> Path:
    """Where a rig sweep writing ``output`` keeps its time series: ``NAME-timeseries.parquet`` beside it."""
    output = Path(output)
    return output.with_name(f"{output.stem}-timeseries.parquet")


# -- the session -----------------------------------------------------------------------------------------------
@dataclass
class RigSession:
    """One connection to the site at ``backend.rig``, over which the controller runs a whole test.

    Parameters
    ----------
    backend : SubstructuredBackend
        With ``rig`` set; its controller options (prediction, filter) apply.
    params : ModelParams
        The first point's parameters: they fix the controller step for the session.
    log : TimeSeriesLog or None
        Where every tick goes (None: nowhere).
    stop_request : StopRequest
        Checked at every tick; a set request stops the test safely.
    limits : RigLimits
        The client's own limits on the site's readings (stroke, platform
        velocity, load cell); beyond one the test stops safely.
    session : int
        Index of this session in the test (0 for the first, more after resumes).
    stop_periods : int
        Forcing periods of the safe stop's ramp to zero (:meth:`stop`).
    """

    backend: Any
    params: ModelParams
    log: TimeSeriesLog | None = None
    stop_request: StopRequest = field(default_factory=StopRequest)
    limits: RigLimits = field(default_factory=RigLimits)
    session: int = 0
    stop_periods: int = STOP_PERIODS

    def __post_init__(self) -> None:
        host, port = parse_rig_url(self.backend.rig)
        self.dt = self.backend.step(self.params)
        self.state = self.backend.initial_state(self.params, 0.0, 0.0, 0.0, 0.0)
        self.rig = RemoteRig(host, port)
        self.ticks = 0  # controller ticks run in this session (the time axis: t = ticks dt)
        self.turns = 0  # whole turns of theta taken out of the state so far (the site reports it unwrapped)
        self.hf_run = 0  # periods in a row with high-frequency growth (the instability monitor)
        self.readings = np.empty(4)  # f_meas, fs_true (not measured remotely), theta_x, x_meas
        self.late_ticks = 0  # replies that came more than a step after their simulated time (real time missed)
        self.closed = False
        self.stopped: RigStopped | None = None  # set when the test had to stop (a limit, an unstable loop)
        self._take(self.rig.reply)
        # Time 0 on the wall clock, a step before the first reply: a real-time site paces every later reply
        # from its first, so a reply more than a step behind that schedule missed real time.
        self.wall_start: float | None = None

    # -- parameters ------------------------------------------------------------------------------------------
    def realised(self, params: ModelParams) -> ModelParams:
        """``params`` at the session's step: ``fe`` moved to ``1 / (n dt)`` with whole ``n`` where it differs."""
        n = max(1, round(1.0 / (params.fe * self.dt)))
        if abs(n * self.dt * params.fe - 1.0) <= 1e-12:
            return params
        return params.replace(fe=1.0 / (n * self.dt))

    # -- ticks -----------------------------------------------------------------------------------------------
    def _take(self, reply: np.ndarray) -> None:
        x_meas, th_x, xd, thd, _acc, f_meas = reply[:6]
        s = self.state
        s[S_X], s[S_XDOT], s[S_THETA], s[S_THETADOT] = x_meas, xd, th_x - TWO_PI * self.turns, thd
        self.readings[:] = (f_meas, math.nan, s[S_THETA], x_meas)

    def _limit_exceeded(self, reply: np.ndarray) -> str:
        """The first of the client's limits that the reading ``reply`` breaks ('' when none)."""
        lim = self.limits
        if abs(reply[2]) > lim.velocity:
            return f"platform velocity {reply[2]:.4g} m/s beyond the limit +-{lim.velocity:g} m/s"
        if abs(reply[5]) > lim.force:
            return f"load cell {reply[5]:.4g} N beyond the limit +-{lim.force:g} N"
        return ""

    def run(
        self, params: ModelParams, transient: int, record: int, *, value: float = math.nan, point: int = -1,
        ramp: Sequence[ModelParams] = (),
    ) -> tuple[Status, int, np.ndarray, np.ndarray]:  # fmt: skip
        """Run ``transient + record`` forcing periods at ``params``; returns ``(status, done, records, trips)``.

        The first ``len(ramp)`` periods of the transient run at the ramp's
        parameters instead, one each (:meth:`pendsweep.sweep.SweepConfig.ramp_params`).
        ``records`` are float64[record, 8] (NaN where not reached), ``trips``
        the round trips of the ticks [s]. A limit or an unstable loop ramps
        the rig down and returns status ``unstable`` with :attr:`stopped` set
        (the caller keeps the point, then raises it); a stop request raises
        :class:`_StopNow` (see :func:`run_guarded`); a lost reply raises
        :class:`RigStopped` at once.
        """
        records = np.full((record, N_RECORD_COLUMNS), np.nan)
        trips: list[float] = []
        for period in range(transient + record):
            if self.stop_request:  # at a period boundary: the ramp down starts at forcing phase 0
                raise _StopNow()
            at = ramp[period] if period < len(ramp) else params
            code, reason = self._period(at, records, period - transient, value, point, trips)
            if code != STATUS_OK:
                try:
                    self.stop(at, f"stopped at {value:g}: {reason}")
                except RigStopped as exc:
                    self.stopped = exc  # the caller keeps this point (status unstable), then ends the test
                return Status.UNSTABLE, period, records, np.asarray(trips)
        return Status.OK, transient + record, records, np.asarray(trips)

    def _period(self, params, records, r_idx, value, point, trips) -> tuple[int, str]:
        """One forcing period at ``params`` (record row ``r_idx``, < 0: none); ``(status code, reason)``."""
        params = self.realised(params)
        cfg = self.backend.loop_settings(params, dt=self.dt)
        p = params.kernel_array()
        n = cfg.steps_per_period
        table = forcing_table(cfg.alpha, n)
        trace = np.full((n, N_TRACE_COLUMNS), np.nan) if self.log is not None else np.empty((n, 0))
        row = np.empty(N_RECORD_COLUMNS)
        record_open(row)
        sum_x2 = sum_h2 = 0.0
        code, reason = STATUS_OK, ""
        first_trip = len(trips)
        for jstep in range(n):
            command, slope = client_tick(self.state, p, cfg, table, jstep, self.ticks, self.readings, row, trace[jstep])
            reply = self._step(command, slope, trips)
            x = self.state[S_X]
            d2 = reply[4] * self.dt * self.dt  # the daq acceleration: an LVDT's second difference measures its noise
            sum_x2 += x * x
            sum_h2 += d2 * d2
            code = stroke_status(x, self.state[S_Y], cfg.stroke)
            reason = self._limit_exceeded(reply) if code == STATUS_OK else "stroke"
            if reason:
                code = STATUS_UNSTABLE
                break
        if code == STATUS_OK and high_frequency_growth(sum_x2, sum_h2, n, self.dt, TWO_PI * cfg.fe, cfg):
            self.hf_run += 1
        elif code == STATUS_OK:
            self.hf_run = 0
        before = self.state[S_THETA]
        code, self.hf_run = close_period(self.state, row, records, r_idx, code, self.hf_run, False, cfg)
        self.turns += int(round((before - self.state[S_THETA]) / TWO_PI))
        if self.log is not None:
            self._log(trace[: len(trips) - first_trip], value, point, trips[first_trip:])
        if code != STATUS_OK and not reason:
            reason = "the instability monitor (high-frequency growth of the platform's motion)"
        return code, reason

    def _step(self, command: float, slope: float, trips: list[float]) -> np.ndarray:
        try:
            reply = self.rig.step(command, slope, (self.ticks + 1) * self.dt, commit=self.ticks > 0)
        except RunFailure as exc:
            self._abandon()
            raise RigStopped(f"{exc}; the rig could not be ramped down (no reply)") from None
        self.ticks += 1
        now = time.perf_counter()
        if self.wall_start is None:
            self.wall_start = now - self.dt
        elif now - self.wall_start > (self.ticks + 1) * self.dt:
            self.late_ticks += 1
        trips.append(self.rig.round_trips[-1])
        self._take(reply)
        return reply

    def _log(self, trace: np.ndarray, value: float, point: int, trips: list[float]) -> None:
        extra = np.column_stack(
            [
                np.full(len(trips), value),
                np.asarray(trips),
                np.full(len(trips), self.session),
                np.full(len(trips), point),
            ]
        )
        self.log.append(np.hstack([trace, extra]))

    # -- ending ----------------------------------------------------------------------------------------------
    def stop(self, params: ModelParams, reason: str, exit_code: int = 1) -> None:
        """Ramp the forcing to zero over :attr:`stop_periods`, let the model come to rest, close; raise :class:`RigStopped`."""
        stop_periods = self.stop_periods
        self.stop_request = StopRequest()  # the ramp itself must run; a second signal is not a new stop
        lvdt = max(self.backend.lvdt_resolution, 1e-5)
        try:
            for k in range(stop_periods):
                self._ramp_period(params.replace(alpha=params.alpha * (1.0 - (k + 1) / stop_periods)))
            for _ in range(stop_periods):  # the model decays with its own damping, the command continuous
                if abs(self.state[S_Y]) < lvdt and abs(self.state[S_X]) < lvdt:
                    break
                self._ramp_period(params.replace(alpha=0.0))
        except RigStopped as exc:
            raise RigStopped(f"{reason}; {exc}", exit_code) from None
        self.close()
        raise RigStopped(f"{reason}; forcing ramped to zero over {stop_periods} periods, die sent", exit_code)

    def _ramp_period(self, params: ModelParams) -> None:
        scratch = np.full((0, N_RECORD_COLUMNS), np.nan)
        self._period(params, scratch, -1, math.nan, -1, [])

    def close(self) -> None:
        """Commit the last step and send die (the session ends normally)."""
        if not self.closed:
            self.closed = True
            self.rig.close()

    def _abandon(self) -> None:
        if not self.closed:
            self.closed = True
            self.rig.sock.close()


class _StopNow(Exception):
    """Raised inside a period when a stop was requested; :func:`run_guarded` turns it into a safe stop."""


def run_guarded(session: RigSession, params: ModelParams, transient: int, record: int, **kw):
    """:meth:`RigSession.run` with a requested stop (a signal) turned into the safe stop at ``params``."""
    try:
        return session.run(params, transient, record, **kw)
    except _StopNow:
        request = session.stop_request
        session.stop(params, request.reason, request.exit_code)


__all__ = [
    "NUMERICAL_PARAMETERS",
    "PHYSICAL_PARAMETERS",
    "STOP_PERIODS",
    "RigSession",
    "RigStopped",
    "StopRequest",
    "TimeSeriesLog",
    "check_sweepable",
    "run_guarded",
    "stop_on_signals",
    "timeseries_path",
]
