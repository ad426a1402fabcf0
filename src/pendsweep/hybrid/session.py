"""A continuous hybrid test on a remote rig: one connection for a whole sweep branch (or both).

The paper's hybrid bifurcation diagram (Fig. 11(a1)) is measured by stepping
a parameter of the numerical model *while the test runs*: the specimen
cannot be put back into a chosen state between points. A :class:`RigSession`
is that test. It holds one connection to a site (a :class:`~pendsweep.backends.transports.RigLink`,
for ``tcp://`` a :class:`~.client.RemoteRig`)
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
  step (:meth:`pendsweep.studies.sweep.SweepConfig.ramp_params`).

The safe stop (:meth:`RigSession.stop`): at the end of the forcing period
in progress (a limit or the instability monitor: at once), the forcing amplitude is ramped
to zero over ``stop_periods`` forcing periods (linearly, tick by tick, from
where the forcing was: the force stays continuous), then the command sent is tapered to
zero over as many periods again (the actuator brought home while the model
runs on), the last step committed and the site told ``die``; a finished
test ends the same way. A signal (SIGINT, SIGTERM), a limit (stroke, velocity, force
of :class:`~.rig.RigLimits`) or the instability monitor triggers it; a lost
or garbled reply cannot be ramped down (the rig is not answering) and
closes the connection at once.

The time series (:class:`TimeSeriesLog`) of every controller tick is kept
as the test runs, flushed in parts every few seconds (a killed client
loses at most that), and consolidated into one parquet file of kind
``trace`` that :func:`pendsweep.measured.records.read_record` reads as a
``substructured`` record (``pendsweep diagnose``, ``pendsweep sync``).
"""

from __future__ import annotations

import json
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

from ..backends.status import Status
from ..backends.transports import continuous_transport
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
from ..model.params import KERNEL_FIELDS, ModelParams
from .rig import RigLimits

#: Parameters of the numerical model, which the client integrates and a session may change between points.
NUMERICAL_PARAMETERS = ("alpha", "fe", "M", "C", "K", "k3")
#: Parameters of the physical substructure (pendulum and platform), which only the site can set.
PHYSICAL_PARAMETERS = (*(name for name in KERNEL_FIELDS if name not in NUMERICAL_PARAMETERS), "M2", "C2")
#: Default forcing periods of the safe stop's ramp to zero.
STOP_PERIODS = 5
#: Seconds between flushes of the time series (at most this much of it is lost when the client is killed).
TIMESERIES_FLUSH_SECONDS = 2.0
#: The command's column in a trace row.
_TRACE_COMMAND = TRACE_COLUMNS.index("command")
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
        The file's ``pendsweep`` metadata (kind ``trace``, see :mod:`pendsweep.measured.logs`).
    parameter : str
        The swept parameter's column name.
    flush_seconds : float
        Longest time buffered rows wait for a write.

    Columns: :data:`~pendsweep.kernels._substructured.TRACE_COLUMNS` (the
    substructured trace's: ``t, Fe, y`` (y*), ``ydot, command, x, xdot,
    x_meas, theta, theta_true, thetadot, Fs, Fs_true, F_fb, sync_error``;
    the site's readings where the client has them, NaN where it has not),
    the parameter's value (NaN during a ramp down), ``fe_realised`` [Hz] (the
    forcing frequency on whole controller ticks), ``round_trip`` [s],
    ``session``, ``point`` (-1 during a ramp down) and ``direction`` (+1 up,
    -1 down, 0 the ramp down).
    """

    def __init__(
        self, path: Path, metadata: dict, parameter: str, flush_seconds: float = TIMESERIES_FLUSH_SECONDS,
        resume: bool = True,
    ) -> None:  # fmt: skip
        from ..engine.results import schema_with_metadata

        self.path = Path(path)
        self.parts = self.path.with_name(self.path.name + ".parts")
        if not resume:  # a new test: an earlier test's series at this path goes
            self.path.unlink(missing_ok=True)
            for old in self.parts.glob("*") if self.parts.is_dir() else ():
                old.unlink()
        self.parts.mkdir(parents=True, exist_ok=True)
        self.parameter = parameter
        self.flush_seconds = flush_seconds
        names = [*TRACE_COLUMNS, parameter, "fe_realised", "round_trip", "session", "point", "direction"]
        self.schema = schema_with_metadata(pa.schema([(n, pa.float64()) for n in names]), metadata)
        self._buffer: list[np.ndarray] = []
        self._last_flush = time.monotonic()
        numbers = [int(name[:6]) for name in (*self._merged(), *(p.name for p in self._unmerged()))]
        self._next = 1 + max(numbers, default=-1)  # never a name an earlier part had

    def _merged(self) -> list[str]:
        """The parts already merged into ``path`` (its metadata lists them)."""
        if not self.path.is_file():
            return []
        meta = pq.read_schema(self.path).metadata or {}
        return json.loads(meta.get(b"merged_parts", b"[]"))

    def _unmerged(self) -> list[Path]:
        """Parts not yet in ``path`` (a merge killed before it removed its parts leaves merged ones behind)."""
        merged = set(self._merged())
        return [p for p in sorted(self.parts.glob("[0-9]*.parquet")) if p.name not in merged]

    def sessions_so_far(self) -> int:
        """Sessions already kept, merged or not (a resumed test's new session gets the next index)."""
        tables = [pq.read_table(p, columns=["session"]) for p in self._unmerged()]
        if self.path.is_file():
            tables.append(pq.read_table(self.path, columns=["session"]))
        return 1 + max((int(np.max(t["session"].to_numpy())) for t in tables if t.num_rows), default=-1)

    def append(self, rows: np.ndarray) -> None:
        """Buffer ``rows`` (n, len(columns)); write a part when the last write is older than ``flush_seconds``."""
        self._buffer.append(rows)
        if time.monotonic() - self._last_flush >= self.flush_seconds:
            self.flush()

    def flush(self) -> None:
        """Write the buffered rows as one part, atomically (a killed client leaves whole parts only)."""
        from ..engine.results import atomic_write_table

        self._last_flush = time.monotonic()
        if not self._buffer:
            return
        block = np.concatenate(self._buffer)
        self._buffer = []
        table = pa.Table.from_arrays([pa.array(block[:, j]) for j in range(block.shape[1])], schema=self.schema)
        atomic_write_table(table, self.parts / f"{self._next:06d}.parquet")
        self._next += 1

    def consolidate(self) -> Path:
        """Flush, then merge the parts not yet merged into ``path`` (earlier sessions' rows kept); the parts go.

        ``path`` is rewritten atomically with the names of every part it holds
        in its metadata, before any part is removed: a merge killed half way
        leaves either the old file and all parts, or the new file and parts it
        already holds (skipped next time).
        """
        from ..engine.results import atomic_write_table

        self.flush()
        merged, parts = self._merged(), self._unmerged()
        tables = [pq.read_table(self.path).cast(self.schema)] if self.path.is_file() else []
        tables += [pq.read_table(p).cast(self.schema) for p in parts]
        rows = pa.concat_tables(tables) if tables else self.schema.empty_table()
        names = json.dumps(merged + [p.name for p in parts]).encode()
        atomic_write_table(rows.replace_schema_metadata({**(self.schema.metadata or {}), b"merged_parts": names}),
                           self.path)  # fmt: skip
        for p in self.parts.glob("*"):
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
        self.dt = self.backend.step(self.params)
        self.state = self.backend.initial_state(self.params, 0.0, 0.0, 0.0, 0.0)
        self.rig = continuous_transport(self.backend.rig).open(self.backend.rig)
        self.ticks = 0  # controller ticks run in this session (the time axis: t = ticks dt)
        self.turns = 0  # whole turns of theta taken out of the state so far (the site reports it unwrapped)
        self.hf_run = 0  # periods in a row with high-frequency growth (the instability monitor)
        self.readings = np.empty(4)  # f_meas, fs_true (not measured remotely), theta_x, x_meas
        self.late_ticks = 0  # replies that came more than a step after their simulated time (real time missed)
        self.closed = False
        self.stopping = False  # ramping down: no limit breaks a period
        self.last_sent = 0.0  # the command sent last [m]
        self.broke_at = 0  # the tick of its period at which the last period broke off (0: it ran whole)
        self.direction = 1.0  # the branch in the time series: +1 up, -1 down, 0 the ramp down
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
        parameters instead, one each (:meth:`pendsweep.studies.sweep.SweepConfig.ramp_params`).
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

    def _period(
        self, params, records, r_idx, value, point, trips, from_step: int = 0,
        envelope: tuple[float, float] = (1.0, 1.0), homing: tuple[float, float] | None = None,
    ) -> tuple[int, str]:  # fmt: skip
        """One forcing period at ``params`` from tick ``from_step`` of it (record row ``r_idx``, < 0: none).

        Returns ``(status code, reason)``. A limit breaks the period off and
        :attr:`broke_at` keeps the tick, where a safe stop's ramp picks the
        forcing up (its phase continuous). While stopping no limit breaks a
        period: the ramp must run. Every tick run is logged, also those of a
        period cut short by a lost reply. ``envelope = (e0, e1)`` scales the
        forcing linearly from ``e0`` at tick ``from_step`` to ``e1`` at the
        period's end (a ramp down). ``homing = (u0, u1)``: the command
        sent is tapered by ``(1 + cos(pi u)) / 2`` with ``u`` going from ``u0``
        to ``u1`` over the period (:meth:`ramp_down`).
        """
        params = self.realised(params)
        cfg = self.backend.loop_settings(params, dt=self.dt)
        p = params.kernel_array()
        n = cfg.steps_per_period
        table = forcing_table(cfg.alpha, n)
        if envelope != (1.0, 1.0):  # on the half-step grid of the table (RK4's stages)
            e0, e1 = envelope
            half_steps = np.arange(table.shape[0]) / 2.0
            table = table * (e0 + (e1 - e0) * np.clip((half_steps - from_step) / (n - from_step), 0.0, 1.0))
        trace = np.full((n, N_TRACE_COLUMNS), np.nan) if self.log is not None else np.empty((n, 0))
        row = np.empty(N_RECORD_COLUMNS)
        record_open(row)
        sum_x2 = sum_h2 = 0.0
        code, reason = STATUS_OK, ""
        first_trip = len(trips)
        self.broke_at = 0
        try:
            for jstep in range(from_step, n):
                command, slope = client_tick(
                    self.state, p, cfg, table, jstep, self.ticks, self.readings, row, trace[jstep - from_step]
                )
                if homing is not None:
                    if self.log is not None:  # the trace shows the command in force, the tapered one sent last
                        trace[jstep - from_step, _TRACE_COMMAND] = self.last_sent
                    command, slope = _tapered(command, slope, homing, (jstep + 1) / n, n * self.dt)
                reply = self._step(command, slope, trips)
                self.last_sent = command
                x = self.state[S_X]
                d2 = reply[4] * self.dt * self.dt  # the daq acceleration: an LVDT's second difference measures noise
                sum_x2 += x * x
                sum_h2 += d2 * d2
                if self.stopping:
                    continue
                code = stroke_status(x, self.state[S_Y], cfg.stroke)
                reason = self._limit_exceeded(reply) if code == STATUS_OK else "stroke"
                if reason:
                    code, self.broke_at = STATUS_UNSTABLE, (jstep + 1) % n
                    break
        finally:
            if self.log is not None:
                self._log(trace[: len(trips) - first_trip], value, point, trips[first_trip:], params)
        if self.stopping:
            return STATUS_OK, ""
        if code == STATUS_OK and high_frequency_growth(sum_x2, sum_h2, n, self.dt, TWO_PI * cfg.fe, cfg):
            self.hf_run += 1
        elif code == STATUS_OK:
            self.hf_run = 0
        before = self.state[S_THETA]
        code, self.hf_run = close_period(self.state, row, records, r_idx, code, self.hf_run, False, cfg)
        self.turns += int(round((before - self.state[S_THETA]) / TWO_PI))
        if code != STATUS_OK and not reason:
            reason = "the instability monitor (high-frequency growth of the platform's motion)"
        return code, reason

    def _step(self, command: float, slope: float, trips: list[float]) -> np.ndarray:
        try:
            reply = self.rig.step(command, slope, (self.ticks + 1) * self.dt, commit=self.ticks > 0)
        except RunFailure as exc:
            self._abandon()
            raise RigStopped(f"{exc}; the rig could not be ramped down (its connection is lost)") from None
        self.ticks += 1
        now = time.perf_counter()
        if self.wall_start is None:
            self.wall_start = now - self.dt
        elif now - self.wall_start > (self.ticks + 1) * self.dt:
            self.late_ticks += 1
        trips.append(self.rig.round_trips[-1])
        self._take(reply)
        return reply

    def _log(self, trace: np.ndarray, value: float, point: int, trips: list[float], params: ModelParams) -> None:
        extra = np.column_stack(
            [
                np.full(len(trips), value),
                np.full(len(trips), params.fe),  # the realised forcing frequency
                np.asarray(trips),
                np.full(len(trips), self.session),
                np.full(len(trips), point),
                np.full(len(trips), self.direction),
            ]
        )
        self.log.append(np.hstack([trace, extra]))

    # -- ending ----------------------------------------------------------------------------------------------
    def stop(self, params: ModelParams, reason: str, exit_code: int = 1) -> None:
        """:meth:`ramp_down` from ``params``, close, and raise :class:`RigStopped` with ``reason``."""
        try:
            self.ramp_down(params)
        except RigStopped as exc:
            raise RigStopped(f"{reason}; {exc}", exit_code) from None
        raise RigStopped(f"{reason}; forcing ramped to zero over {self.stop_periods} periods, die sent", exit_code)

    def ramp_down(self, params: ModelParams) -> None:
        """Ramp the forcing to zero over :attr:`stop_periods`, bring the actuator home, commit and send die.

        The ramp picks the forcing up where the last period broke off and
        scales its amplitude down linearly, tick by tick, to zero at the end of
        the ramp's last period: the force stays continuous. Then,
        over as many periods again, the command sent is tapered to zero (a
        half cosine, its slope continuous) while the numerical model runs on:
        the pendulum, lightly damped, would keep the oscillator swinging
        through the load cell for minutes, so the platform is brought to its
        centre rather than waited for. Every test ends so, a finished one too:
        a rig is never left mid-stroke.
        """
        self.stop_request = StopRequest()  # the ramp itself must run; a second signal is not a new stop
        self.stopping, self.direction = True, 0.0
        from_step = self.broke_at
        scratch = np.full((0, N_RECORD_COLUMNS), np.nan)
        n = self.backend.loop_settings(self.realised(params), dt=self.dt).steps_per_period
        total = (n - from_step) + (self.stop_periods - 1) * n  # ticks of the ramp
        done = 0
        for _ in range(self.stop_periods):
            ticks = n - from_step
            envelope = (1.0 - done / total, 1.0 - (done + ticks) / total)
            self._period(params, scratch, -1, math.nan, -1, [], from_step, envelope=envelope)
            done, from_step = done + ticks, 0
        for k in range(self.stop_periods):
            homing = (k / self.stop_periods, (k + 1) / self.stop_periods)
            self._period(params.replace(alpha=0.0), scratch, -1, math.nan, -1, [], homing=homing)
        self.close()

    def close(self) -> None:
        """Commit the last step and send die (the session ends normally)."""
        if not self.closed:
            self.closed = True
            self.rig.close()

    def _abandon(self) -> None:
        if not self.closed:
            self.closed = True
            self.rig.abort()


def _tapered(command: float, slope: float, homing: tuple[float, float], at: float, period: float):
    """``(command, slope)`` times the homing taper ``(1 + cos(pi u)) / 2`` at the fraction ``at`` of a period [s]."""
    u0, u1 = homing
    u = u0 + (u1 - u0) * at
    weight = 0.5 * (1.0 + math.cos(math.pi * u))
    rate = -0.5 * math.pi * math.sin(math.pi * u) * (u1 - u0) / period  # d(weight)/dt [1/s]
    return command * weight, slope * weight + command * rate


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
