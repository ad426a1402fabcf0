"""The paper's experiment on a remote rig: a hybrid bifurcation diagram swept through one continuous test.

``pendsweep alpha --mode continue --backend substructured -B rig=tcp://HOST:PORT``
steps the numerical model's parameter *while the test runs*, as Fig. 11(a1)
was measured: one connection (:class:`~.session.RigSession`) for the whole
branch, and for ``--direction both`` for the up branch and then the down
branch, the hysteresis loop as one test (the down branch starts where the
up branch ended; in process, ``--direction loop`` is the same experiment).

What differs from an in-process continue sweep, and why
------------------------------------------------------
* The pendulum cannot be kicked from the client: the pivot moves
  vertically, so the hanging pendulum is an invariant of the rig, and
  Coulomb friction holds it at rest against small disturbances well past
  the stability boundary (at 24 N the emulated system returns to rest from
  0.001 rad and leaves it from 0.01 rad). A point at rest therefore stays at
  rest until a hand nudges the pendulum, as the paper's operators did
  (Fig. 8: "instigated by perturbing the pendulum by theta = 0.1 rad"):
  where an in-process sweep would kick, the test asks for a nudge in one
  line (a ``pendsweep site`` takes it as SIGUSR1, ``--nudge`` rad);
  ``kick`` must be 0.
* The first point starts from the site's own state (its ``--theta0``).
* A resumed test (the same command after the client was killed) opens a
  new session: the rig starts from whatever state its site gives, so the
  branch is discontinuous there. That point gets its full transient and
  its rows carry ``restarted = true``; the live plot marks it.
* Nothing is lost: every finished point is in the results file (the scan
  engine's parts), and every controller tick in the time series
  (:class:`~.session.TimeSeriesLog`, ``NAME-timeseries.parquet``) up to
  its last flush.
* A signal, a limit, the instability monitor or a lost reply stops the
  test safely (:meth:`~.session.RigSession.stop`) and raises
  :class:`~.session.RigStopped` (exit 130 after SIGINT, 1 otherwise),
  with everything so far written.

While it runs, every point prints one line: the value, the motion class,
theta_max, the emulated system's theta_max at this value (an in-process
emulated continue sweep of the same values, computed first:
:meth:`pendsweep.studies.sweep.SweepConfig.emulated_reference`) and their
difference, and the test time done and left (test seconds, and wall seconds
at the pace so far). ``RigWatch.plot`` is redrawn after every point: the
hybrid diagram growing over the emulated one.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from ..analysis.classify import at_rest, classify_runs
from ..backends import PointRun
from ..backends.status import Status
from ..backends.transports import continuous_transport
from ..errors import ConfigError
from ..hybrid.session import (
    STOP_PERIODS,
    TIMESERIES_FLUSH_SECONDS,
    RigSession,
    RigStopped,
    StopRequest,
    TimeSeriesLog,
    check_sweepable,
    run_guarded,
    stop_on_signals,
    timeseries_path,
)
from ..kernels import N_RECORD_COLUMNS
from ..kernels._layout import REC_THETA_ABSMAX
from ..model.params import PARAM_SPECS
from .sweep_rows import PointResult, classified_fields, unit_key, unit_results


@dataclass(frozen=True)
class RigWatch:
    """What a continuous rig test writes and reports besides its results (none of it changes the results).

    Attributes
    ----------
    timeseries : Path or None
        The time series file (None: not kept); see :func:`timeseries_path`.
    plot : Path or None
        A figure redrawn after every point (.png/.pdf/.svg).
    stop_periods : int
        Forcing periods of the safe stop's ramp to zero (default 5).
    flush_seconds : float
        Longest time the time series waits in memory [s] (default 2).
    reference : bool
        Compare every point with the emulated system at the same value.
    echo : callable or None
        Where the per-point lines go (None: stderr).
    """

    timeseries: Path | None = None
    plot: Path | None = None
    stop_periods: int = STOP_PERIODS
    flush_seconds: float = TIMESERIES_FLUSH_SECONDS
    reference: bool = True
    echo: Callable[[str], None] | None = None

    def say(self, line: str) -> None:
        if self.echo is not None:
            self.echo(line)
        else:
            print(line, file=sys.stderr, flush=True)


def default_watch(watch: RigWatch | None, output: Path | None) -> RigWatch:
    """``watch`` (default :class:`RigWatch`) with its time series beside ``output`` when it names none."""
    watch = RigWatch() if watch is None else watch
    if watch.timeseries is None and output is not None:
        watch = dataclasses.replace(watch, timeseries=timeseries_path(output))
    return watch


def address_free_hash(config: dict) -> str:
    """The hash of a rig test's configuration without the rig's address: a site restarted on another port (or a
    rig reached through another host) is the same specimen, and its test resumes there."""
    from ..engine.results import config_hash

    return config_hash({**config, "backend_options": {**config["backend_options"], "rig": ""}})


def check_rig_sweep(config, backend) -> None:
    """Refuse (``ConfigError``) a sweep that a remote rig cannot run."""
    check_sweepable(config.parameter, backend.rig)
    if config.mode == "multistart":
        raise ConfigError("a remote rig has one specimen in one state: use --mode continue (or fresh), not multistart")
    if config.mode == "fresh" and config.transient != "fixed":
        raise ConfigError(
            "a remote rig starts every fresh point from its own initial state: --transient auto needs --mode continue"
        )
    if config.mode == "continue":
        continuous_transport(backend.rig)  # one connection for the whole test: its transport must hold one
    if config.mode == "continue" and config.kick:
        raise ConfigError(
            f"kick = {config.kick:g} rad: a remote rig's pendulum cannot be kicked from the client; give --kick 0"
        )
    if config.mode == "continue" and tuple(config.initial) != tuple(type(config).initial):
        raise ConfigError(
            f"initial = {list(config.initial)}: a remote rig starts from its site's own state; set the pendulum's "
            "angle at the site (pendsweep site --theta0)"
        )


def rig_test(
    config, backend, resume: dict, watch: RigWatch, finished_rows: pa.Table | None = None,
    emulated: pa.Table | None = None,
) -> Iterator:  # fmt: skip
    """The whole continuous test (every branch of ``config``) through one session; yields each point's unit.

    ``resume`` names the finished units (:func:`pendsweep.studies.sweep_rows.resume_info`):
    they are skipped, and the first unfinished one opens a new session
    (``restarted``). ``finished_rows`` are their rows (for the live plot);
    ``emulated`` the rows of the emulated reference sweep
    (:meth:`pendsweep.studies.sweep.SweepConfig.emulated_reference`; None: no comparison).
    """
    walk = [(direction, i) for direction, indices in config.branches() for i in indices]
    todo = [(direction, i) for direction, i in walk if unit_key(direction, i, 0) not in resume]
    log = None
    if watch.timeseries is not None:
        meta = timeseries_metadata(config, backend)
        log = TimeSeriesLog(watch.timeseries, meta, config.parameter, watch.flush_seconds, resume=bool(resume))
    if not todo:  # every point finished: a merge the last run could not end, if any, ends here
        if log is not None:
            log.consolidate()
        return
    reference = theta_max_by_unit(emulated) if emulated is not None else {}
    progress = _Progress(config, backend, len(todo), watch, reference)
    plot = _LivePlot(watch.plot, config, emulated, finished_rows) if watch.plot is not None else None
    restarted = len(todo) < len(walk)
    request = StopRequest()
    params = config.params_at(config.values[todo[0][1]])
    try:  # connecting (up to 10 s to a starting site) can be interrupted: nothing has moved yet
        index = log.sessions_so_far() if log is not None else 0
        session = RigSession(backend, params, log, request, session=index, stop_periods=watch.stop_periods)
    except KeyboardInterrupt:
        if log is not None:
            log.consolidate()
        raise RigStopped(f"stopped by SIGINT while connecting to {backend.rig}; the test had not begun", 130) from None
    progress.session_opened(session, restarted, config.values[todo[0][1]])
    previous = None
    rested = False  # the last point ended at rest: an in-process sweep would kick the pendulum now
    try:
        with stop_on_signals(request):
            for direction, i in todo:
                value = config.values[i]
                params = config.params_at(value)
                session.direction = 1.0 if direction == "up" else -1.0
                if rested:
                    progress.ask_for_nudge(value)
                ramp = _ramp_of(config, previous, value)
                late_before = session.late_ticks
                run, settled, used = _point(config, session, params, ramp, value, i)
                motion = classify_runs(backend, [params], [run], config.rest_threshold, config.evidence)[0]
                result = PointResult(
                    direction, i, 0, value, run, False, settled=settled, transient_used=used, restarted=restarted,
                    late_ticks=session.late_ticks - late_before, **classified_fields(motion, backend),
                )  # fmt: skip
                units = unit_results([result], config.parameter, config.transient == "auto")
                yield from units
                progress.point_done(result, session)
                if plot is not None:
                    plot.add(units[0].rows)
                restarted = False
                previous = value
                rested = run.status is Status.OK and at_rest(run.records[:, REC_THETA_ABSMAX], config.rest_threshold)
                if session.stopped is not None:
                    raise session.stopped
            session.ramp_down(params)  # the end of the test: the forcing to zero, never die mid-stroke
    finally:
        if not session.closed:
            # the consumer stopped early (an error writing results, a closed generator): the rig ramps down all the same
            with contextlib.suppress(RigStopped):
                session.stop(params, "the test ended early")
        if log is not None:
            log.consolidate()


def _ramp_of(config, previous: float | None, value: float) -> list:
    """The in-process sweep's ramp, period for period (none at a test's or a new session's first point)."""
    return config.ramp_params(previous, value) if previous is not None and config.ramp_periods else []


def _point(config, session: RigSession, params, ramp, value: float, point: int):
    """One point's transient (fixed, or until it settles) and record; ``(run, settled, transient used)``."""
    transient = config.transient_periods
    if config.transient == "auto":
        transient = 0
        run_guarded(session, params, len(ramp), 0, value=value, point=point, ramp=ramp)
        settled, used = _settle(config, session, params, value, point)
        if session.stopped is not None:
            return _stopped_run(config, session), False, used
        used += len(ramp)
        ramp = []
    status, done, records, trips = run_guarded(
        session, params, transient, config.record_periods, value=value, point=point, ramp=ramp
    )
    run = PointRun(records, session.state.copy(), status, done, _timing(trips))
    if config.transient == "auto":
        return run, settled, used
    return run, False, config.transient_periods


def _stopped_run(config, session: RigSession) -> PointRun:
    """The point at which the test had to stop while settling: no record, status unstable."""
    records = np.full((config.record_periods, N_RECORD_COLUMNS), np.nan)
    return PointRun(records, session.state.copy(), Status.UNSTABLE, 0, None)


def _settle(config, session: RigSession, params, value, point) -> tuple[bool, int]:
    """Run until the record settles (the in-process rule, :func:`pendsweep.studies.basins.settle_runs`) or the cap."""
    from .basins import settle_runs, settle_tolerance

    system = _SessionMap(session, params, value, point)
    settled = settle_runs(
        system, session.state[None].copy(), config.max_transient_periods, rest_threshold=config.rest_threshold,
        tol=settle_tolerance(session.backend),
    )  # fmt: skip
    return bool(settled.settled[0]), int(settled.periods_done[0])


@dataclass
class _SessionMap:
    """A session as the stroboscopic map :func:`pendsweep.studies.basins.settle_runs` advances (one run: the rig)."""

    session: RigSession
    params: Any
    value: float
    point: int

    def advance(self, states, periods, ids):
        status, _, records, _ = run_guarded(self.session, self.params, 0, periods, value=self.value, point=self.point)
        code = 0 if status is Status.OK else 2
        return records[None], self.session.state[None].copy(), np.array([code], dtype=np.int64)

    def scales_for(self, ids, records):
        from ..analysis.attractors import section_scales_many

        return section_scales_many(records, self.params.omega_e, self.params.omega_p)


def _timing(trips: np.ndarray) -> np.ndarray | None:
    """50th, 99th percentile and largest round trip [s] (None when no tick ran)."""
    if not trips.size:
        return None
    return np.array([np.quantile(trips, 0.5), np.quantile(trips, 0.99), trips.max()])


def timeseries_metadata(config, backend) -> dict[str, Any]:
    """The time series' metadata: a substructured trace (kind ``trace``, every tick) of the sweep's base model."""
    from .._version import __version__

    return {
        "kind": "trace",
        "backend": "substructured",
        "params": config.base_params.to_dict(),
        "backend_options": backend.options(),
        "stride": 1,
        "sweep": config.to_dict(),
        "parameter": config.parameter,
        "package_version": __version__,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def theta_max_by_unit(rows: pa.Table) -> dict[tuple[str, int], float]:
    """theta_max [rad] over each ``(direction, point)``'s record."""
    swing = rows.group_by(["direction", "point"]).aggregate([("theta_absmax", "max")])
    keys = zip(swing["direction"].to_pylist(), swing["point"].to_pylist(), swing["theta_absmax_max"].to_pylist())
    return {(d, int(p)): float(m) for d, p, m in keys}


class _Progress:
    """The per-point lines of a continuous test (module docstring)."""

    def __init__(self, config, backend, points: int, watch: RigWatch, reference: dict) -> None:
        self.config, self.backend, self.watch, self.reference = config, backend, watch, reference
        self.left = points
        self.start = time.monotonic()
        self.periods_done = 0
        self.spec = PARAM_SPECS[config.parameter]

    def session_opened(self, session: RigSession, restarted: bool, value: float) -> None:
        where = self.backend.rig
        if restarted:
            self.watch.say(
                f"resuming at {self.config.parameter} = {value:g} {self.spec.unit} with a new session at {where}: "
                "the rig starts from its site's own state (rows marked restarted)"
            )
        else:
            self.watch.say(f"continuous test at {where}: {self.left} points, controller step {session.dt:g} s")

    def ask_for_nudge(self, value: float) -> None:
        """The pendulum rests where an in-process sweep would kick it: only a hand at the rig can (the paper's)."""
        self.watch.say(
            f"{self.config.parameter} = {value:g} {self.spec.unit}: the pendulum is at rest; nudge it to leave the "
            "semi-trivial branch (a pendsweep site: kill -USR1 its pid)"
        )

    def point_done(self, result: PointResult, session: RigSession) -> None:
        config = self.config
        self.left -= 1
        self.periods_done += config.record_periods + result.transient_used
        period_s = 1.0 / config.params_at(result.value).fe
        swing = float(np.nanmax(result.run.records[:, REC_THETA_ABSMAX], initial=np.nan))
        emulated = self.reference.get((result.direction, result.point))
        compare = "" if emulated is None else f" | emulated {emulated:.3f} ({swing - emulated:+.3f})"
        wall = time.monotonic() - self.start
        per_period = wall / max(self.periods_done, 1)
        left_periods = self.left * (config.transient_periods + config.record_periods)
        self.watch.say(
            f"{config.parameter} = {result.value:g} {self.spec.unit} {result.direction}: {result.motion:<14} "
            f"theta_max {swing:.3f} rad{compare} | test {session.ticks * session.dt:.0f} s, "
            f"left {left_periods * period_s:.0f} s of test, ~{left_periods * per_period:.0f} s wall"
            f"{' (restarted)' if result.restarted else ''}"
        )


class _LivePlot:
    """The hybrid diagram growing over the emulated one, rewritten atomically after every point."""

    def __init__(self, path: Path, config, emulated: pa.Table | None, finished_rows: pa.Table | None) -> None:
        self.path, self.config, self.emulated = Path(path), config, emulated
        self.tables = [finished_rows] if finished_rows is not None and finished_rows.num_rows else []

    def add(self, rows: pa.Table) -> None:
        self.tables.append(rows)
        rows = pa.concat_tables(self.tables, promote_options="permissive")
        draw_hybrid_diagram(rows, self.emulated, self.config, self.path)


def draw_hybrid_diagram(rows: pa.Table, emulated: pa.Table | None, config, path: Path) -> Path:
    """theta peaks of the hybrid test (by branch, restarts circled) over the emulated system's, written atomically."""
    from ..canvas import new_figure

    fig = new_figure((8, 5))
    ax = fig.add_subplot(1, 1, 1)
    name = config.parameter
    if emulated is not None and emulated.num_rows:
        ax.plot(emulated[name].to_numpy(), emulated["theta_peak"].to_numpy(), ".", color="0.75", ms=3,
                label="emulated system")  # fmt: skip
    colours = {"up": "tab:blue", "down": "tab:orange", "none": "tab:blue"}
    direction = np.asarray(rows["direction"].to_pylist())
    value, peak = rows[name].to_numpy(), rows["theta_peak"].to_numpy()
    for d in ("up", "down", "none"):
        mask = direction == d
        if mask.any():
            ax.plot(value[mask], peak[mask], ".", color=colours[d], ms=4, label=f"hybrid test, {d}")
    if "restarted" in rows.column_names:
        restarted = np.asarray(rows["restarted"].to_pylist(), dtype=bool)
        if restarted.any():
            ax.plot(
                value[restarted], peak[restarted], "o", mfc="none", mec="red", ms=8, label="restarted (new session)"
            )
    spec = PARAM_SPECS[name]
    ax.set(xlabel=f"{name} [{spec.unit}]", ylabel=r"$\theta_x$ peak [rad]",
           title=f"hybrid bifurcation diagram, {len(set(zip(direction, rows['point'].to_pylist())))} points")  # fmt: skip
    ax.set_xlim(min(config.values), max(config.values))
    ax.legend(loc="upper left", fontsize=8, frameon=False)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


__all__ = [
    "RigWatch",
    "check_rig_sweep",
    "default_watch",
    "draw_hybrid_diagram",
    "rig_test",
    "theta_max_by_unit",
]
