"""Sweep planner: step one model parameter and record theta peaks.

One function, :func:`run_sweep`, in the spirit of an orbit diagram:
``(backend, parameter, values; transient_periods, record_periods, initial)``.

Modes
-----
``continue``
    The state is carried from point to point along a branch, as a physical
    experiment does. Before every point after the first, if the pendulum is
    at rest (max |theta| over the recorded periods below ``rest_threshold``,
    one encoder pulse by default) it is perturbed by ``theta += kick``, as in
    the paper. A branch whose point diverged restarts from ``initial``.
``fresh``
    Every point starts from ``initial``.
``multistart``
    ``starts`` initial conditions per point: start 0 is ``initial``, the
    others draw theta uniformly on (-pi, pi] and thetadot uniformly on
    (-omega_p, omega_p) from ``numpy.random.default_rng([seed, point])``,
    so each point's starts are reproducible whatever the execution order.

Directions ``up`` and ``down`` traverse the values in ascending and
descending order; ``both`` runs the two branches (in parallel), which
exposes hysteresis; ``loop`` runs up, then down from where the up branch
ended, as one continuous experiment (a remote rig's ``both`` runs so, over
one connection: :mod:`pendsweep.studies.rig_sweep`). ``ramp_periods`` moves
the parameter linearly over that many periods at the start of every
continue point instead of stepping it. Fresh and multistart points are independent, so their
``direction`` column is ``"none"`` and they run in parallel.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from ..analysis.classify import EVIDENCE_MODES, at_rest, classify_runs
from ..backends import BACKENDS, PointRun, make_backend
from ..backends.status import Status
from ..engine.executors import Executor
from ..engine.results import run_metadata
from ..engine.scan import DEFAULT_MAX_WORK, Finished, UnitResult, Work, run_scan, sample_indices
from ..errors import ConfigError
from ..kernels._layout import REC_THETA_ABSMAX
from ..model.params import ENCODER_RESOLUTION, PARAM_SPECS, ModelParams, check_value
from .sweep_rows import PointResult, classified_fields, resume_info, unit_key, unit_results

if TYPE_CHECKING:  # rows are built as pyarrow columns; frames only at the API boundary
    import pandas as pd

MODES = ("continue", "fresh", "multistart")
TRANSIENTS = ("fixed", "auto")
#: Most values a sweep's range may hold (checked before the grid is built).
MAX_VALUES = 1_000_000
DIRECTIONS = ("up", "down", "both", "loop")
KEY_COLUMNS = ["direction", "point", "start"]
#: Angle [rad] added to theta at a continue point whose pendulum is at rest (the paper's perturbation).
KICK = 0.1


def value_range(start: float, stop: float, step: float | None = None, points: int | None = None) -> np.ndarray:
    """Grid from ``start`` to ``stop`` inclusive, by ``step`` or with ``points`` values.

    With ``step`` the values are ``start + i*step`` (no accumulated rounding),
    and ``stop`` is included when it lies on the grid (to 1e-9 of a step).
    At most :data:`MAX_VALUES` values (``ConfigError`` before anything is allocated).
    """
    for name, v in (("from", start), ("to", stop)):
        if not math.isfinite(v):
            raise ConfigError(f"range {name} = {v!r} is not finite")
    if not math.isfinite(stop - start):
        raise ConfigError(f"the range from {start:g} to {stop:g} spans more than a float holds; give a narrower one")
    if (step is None) == (points is None):
        raise ConfigError("give exactly one of step or points for a range")
    if points is not None:
        if int(points) < 1:
            raise ConfigError(f"points = {points!r} must be a positive integer")
        _check_count(int(points), f"points = {int(points)}")
        return np.linspace(start, stop, int(points))
    if not math.isfinite(step) or step == 0:
        raise ConfigError(f"step = {step!r} must be finite and non-zero")
    span = stop - start
    if span != 0 and math.copysign(1.0, span) != math.copysign(1.0, step):
        raise ConfigError(
            f"step = {step:g} has the wrong sign for a range from {start:g} to {stop:g}; "
            f"use step {'>' if span > 0 else '<'} 0"
        )
    steps = span / step + 1e-9  # inf for extreme values: refused by the count check
    count = math.floor(steps) + 1 if math.isfinite(steps) else math.inf
    _check_count(count, f"the range from {start:g} to {stop:g} by {step:g}")
    return start + step * np.arange(count)


def _check_count(count: float, what: str) -> None:
    if not count <= MAX_VALUES:
        raise ConfigError(
            f"{what} gives {count:,} values; a sweep takes at most {MAX_VALUES} (use a coarser step or fewer points)"
        )


@dataclass(frozen=True)
class SweepConfig:
    """Everything that determines a sweep's results (stored in every result file).

    Attributes
    ----------
    parameter : str
        Name of the stepped parameter (see ``pendsweep.model.params.PARAM_SPECS``).
    values : tuple of float
        The parameter values, in ascending order.
    model : dict
        Overrides of the default :class:`~pendsweep.model.params.ModelParams`.
    mode, direction : str
        See the module docstring.
    backend : str
        Registered backend name; ``backend_options`` are its options.
    transient_periods, record_periods : int
        Forcing periods discarded, then recorded, at every point (paper: 100, 20).
    transient : {"fixed", "auto"}
        ``fixed`` discards ``transient_periods`` (the paper's protocol).
        ``auto`` integrates each unit in rounds of 25 periods until it has
        settled (:func:`pendsweep.analysis.attractors.settling`: the section repeats
        after n <= 8 periods to 1e-3, normalised, over 24 periods, or the
        rotation number is steady) or ``max_transient_periods`` have passed,
        then records; rows gain ``settled`` and ``transient_periods_used``.
    max_transient_periods : int
        Cap of the adaptive transient [forcing periods].
    initial : tuple of 4 floats
        ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])`` at the first point.
    kick : float
        Perturbation [rad] added to theta when the pendulum is at rest (continue mode).
    rest_threshold : float
        "At rest" means max |theta| below this [rad]; one encoder pulse by default.
    evidence : {"staged", "full"}
        How much the motion classifier simulates past the record of a point
        that its record leaves undecided (:func:`pendsweep.analysis.classify.classify_runs`).
    starts : int
        Initial conditions per point (multistart mode).
    seed : int
        Seed of every random source (multistart draws, backend noise).
    ramp_periods : int
        Continue mode: periods at the start of each transient over which the parameter moves from its last value.
    """

    parameter: str
    values: tuple[float, ...]
    model: dict[str, float] = field(default_factory=dict)
    mode: str = "continue"
    direction: str = "up"
    backend: str = "emulated"
    backend_options: dict[str, Any] = field(default_factory=dict)
    transient_periods: int = 100
    record_periods: int = 20
    transient: str = "fixed"
    max_transient_periods: int = 1000
    initial: tuple[float, float, float, float] = (0.0, 0.0, 0.1, 0.0)
    kick: float = KICK
    rest_threshold: float = ENCODER_RESOLUTION
    evidence: str = "staged"
    starts: int = 1
    seed: int = 0
    ramp_periods: int = 0

    def __post_init__(self) -> None:
        if self.parameter not in PARAM_SPECS:
            raise ConfigError(f"unknown parameter {self.parameter!r}; steppable parameters: {', '.join(PARAM_SPECS)}")
        if len(self.values) == 0:
            raise ConfigError("a sweep needs at least one parameter value")
        vals = tuple(sorted(check_value(self.parameter, v) for v in self.values))
        object.__setattr__(self, "values", vals)
        object.__setattr__(self, "initial", tuple(float(v) for v in self.initial))
        if self.mode not in MODES:
            raise ConfigError(f"mode = {self.mode!r}; choose one of {', '.join(MODES)}")
        if self.direction not in DIRECTIONS:
            raise ConfigError(f"direction = {self.direction!r}; choose one of {', '.join(DIRECTIONS)}")
        if self.evidence not in EVIDENCE_MODES:
            raise ConfigError(f"evidence = {self.evidence!r}; choose one of {', '.join(EVIDENCE_MODES)}")
        if self.transient not in TRANSIENTS:
            raise ConfigError(f"transient = {self.transient!r}; choose one of {', '.join(TRANSIENTS)}")
        for name, lo in (("transient_periods", 0), ("record_periods", 1), ("starts", 1), ("max_transient_periods", 1),
                         ("ramp_periods", 0)):  # fmt: skip
            v = getattr(self, name)
            if int(v) != v or v < lo:
                raise ConfigError(f"{name} = {v!r} must be an integer >= {lo}")
        if len(self.initial) != 4 or not all(math.isfinite(v) for v in self.initial):
            raise ConfigError(f"initial = {self.initial!r} must be 4 finite numbers (y, ydot, theta, thetadot)")
        for name in ("kick", "rest_threshold"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"{name} = {v!r} rad must be a finite number >= 0")
        if self.ramp_periods and self.mode != "continue":
            raise ConfigError(f"ramp_periods = {self.ramp_periods} applies only to continue mode (mode is {self.mode})")
        if self.transient == "fixed" and self.ramp_periods > self.transient_periods:
            raise ConfigError(
                f"ramp_periods = {self.ramp_periods} exceeds transient_periods = {self.transient_periods}: "
                "the ramp is part of the transient"
            )
        # Every value passed check_value, and ModelParams checks each field on its own,
        # so the model at every point is valid when the base model is.
        self.params_at(vals[0])
        self.make_backend()

    # -- derived ----------------------------------------------------------------
    @property
    def base_params(self) -> ModelParams:
        return ModelParams.from_mapping(self.model)

    def params_at(self, value: float) -> ModelParams:
        return self.base_params.replace(**{self.parameter: value})

    def make_backend(self):
        options = dict(self.backend_options)
        cls = BACKENDS.get(self.backend)
        if cls is not None and "seed" in {f.name for f in dataclasses.fields(cls)}:
            options.setdefault("seed", self.seed)  # the sweep's seed drives backend noise too
        backend = make_backend(self.backend, **options)
        for v in (self.values[0], self.values[-1]):
            backend.validate(self.params_at(v))
        if not backend.restartable:  # a remote rig: the protocol cannot put a specimen into a state
            from .rig_sweep import check_rig_sweep

            check_rig_sweep(self, backend)
        return backend

    def ramp_params(self, previous: float, value: float) -> list[ModelParams]:
        """A ramp's first ``ramp_periods - 1`` periods' parameters: period k runs k / ramp_periods of the way."""
        steps = self.ramp_periods
        return [self.params_at(previous + (k / steps) * (value - previous)) for k in range(1, steps)]

    def emulated_reference(self) -> SweepConfig:
        """This sweep with the emulated system, a rig test's reference (its ``both`` one ``loop``, the usual kick)."""
        direction = "loop" if self.direction == "both" else self.direction
        return dataclasses.replace(self, backend="emulated", backend_options={}, direction=direction, kick=KICK)

    def branches(self) -> list[tuple[str, list[int]]]:
        """``(direction label, point indices in traversal order)`` per branch."""
        idx = list(range(len(self.values)))
        if self.mode != "continue":
            return [("none", idx)]
        out = []
        if self.direction in ("up", "both", "loop"):
            out.append(("up", idx))
        if self.direction in ("down", "both", "loop"):
            out.append(("down", idx[::-1]))
        return out

    @property
    def n_units(self) -> int:
        """Number of (branch, point, start) units of work."""
        return sum(len(ix) for _, ix in self.branches()) * (self.starts if self.mode == "multistart" else 1)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        if not self.ramp_periods:  # the paper's step: files written before ramps existed keep their hash
            del d["ramp_periods"]
        d["values"] = list(self.values)
        d["initial"] = list(self.initial)
        d["model"] = self.base_params.to_dict()  # fully resolved
        d["backend_options"] = self.make_backend().options()
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SweepConfig:
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ConfigError(f"unknown sweep key(s): {', '.join(unknown)}; known: {', '.join(sorted(known))}")
        d = dict(d)
        d["values"] = tuple(d.get("values", ()))
        if "initial" in d:
            d["initial"] = tuple(d["initial"])
        return cls(**d)


def multistart_initials(config: SweepConfig, point: int) -> np.ndarray:
    """The ``(starts, 4)`` initial conditions of one point in multistart mode."""
    out = np.empty((config.starts, 4))
    out[0] = config.initial
    if config.starts > 1:
        rng = np.random.default_rng([config.seed, point])
        wp = config.params_at(config.values[point]).omega_p
        n = config.starts - 1
        out[1:, 0] = 0.0
        out[1:, 1] = 0.0
        out[1:, 2] = np.pi - 2 * np.pi * rng.random(n)  # (-pi, pi]
        out[1:, 3] = wp * (2 * rng.random(n) - 1)
    return out


def run_units(
    config: SweepConfig, backend, params: list, states: np.ndarray, threads=None, one_by_one=False, ramped: int = 0
):
    """Transient and record of units: ``(runs, settled, transient periods used)``.

    ``one_by_one`` runs each unit with the backend's ``run_point`` (continue
    mode's scalar path) instead of ``run_points``. ``ramped``: periods of a
    ramp already run, counted in a fixed transient and in those used. With ``transient =
    "auto"`` every unit is integrated in rounds until it settles (see
    :class:`SweepConfig`), on the batched kernel when the backend has one,
    then its record is taken from there.
    """
    n = len(params)
    if config.transient == "fixed":
        transient = config.transient_periods - ramped
        if one_by_one:
            runs = [backend.run_point(q, x, transient, config.record_periods) for q, x in zip(params, states)]
        else:
            runs = backend.run_points(params, states, transient, config.record_periods, threads)
        return runs, np.zeros(n, dtype=bool), np.full(n, config.transient_periods)
    from .basins import BackendMap, EmulatedMap, settle_runs, settle_tolerance  # only adaptive transients need it

    if backend.batched and not one_by_one:
        system = EmulatedMap(
            tuple(params), dt=backend.dt, signum=backend.signum, threads=threads,
            device=backend.device, precision=backend.precision,
        )  # fmt: skip
    else:  # units of one call share their parameters (one point, or one point's starts)
        system = BackendMap(backend, params[0], entropy=(config.seed,), workers=1)
    settled = settle_runs(system, np.asarray(states, dtype=np.float64), config.max_transient_periods,
                          rest_threshold=config.rest_threshold, tol=settle_tolerance(backend))  # fmt: skip
    if one_by_one:
        runs = [backend.run_point(q, x, 0, config.record_periods) for q, x in zip(params, settled.states)]
    else:
        runs = backend.run_points(params, settled.states, 0, config.record_periods, threads)
    return runs, settled.settled, settled.periods_done + ramped


def _classified(config, backend, pending: list[tuple[PointResult, ModelParams]]) -> Iterator[UnitResult]:
    """The pending points of a continue branch, labelled together (one evidence launch), as units."""
    motions = classify_runs(
        backend, [q for _, q in pending], [r.run for r, _ in pending], config.rest_threshold, config.evidence
    )
    labelled = [dataclasses.replace(r, **classified_fields(m, backend)) for (r, _), m in zip(pending, motions)]
    yield from unit_results(labelled, config.parameter, config.transient == "auto")


#: Continue-mode points labelled together: the evidence of a moving point
#: (a 200-period extension and a Lyapunov pair) fills a whole vector group of
#: the batched kernel, so one launch for many points costs about what one
#: point alone does. A crash loses at most these points (recomputed alike).
CLASSIFY_GROUP = 16


def _ramp(backend, params: list[ModelParams], state: np.ndarray) -> tuple[np.ndarray, PointRun | None]:
    """Run the ramp's periods, one each; returns the state after them, or the failed run where one failed."""
    for q in params:
        run = backend.run_point(q, state, 1, 0)
        if run.status is not Status.OK:
            return state, run
        state = run.state
    return state, None


def _continue_branches(config, backend, branches, resume) -> Iterator[UnitResult]:
    """Walk ``branches`` ``[(direction, point indices)]`` in turn, carrying the state (``resume``: finished units)."""
    state = None  # None: start (or restart) from config.initial
    kick_next = False
    previous: float | None = None  # the last point's value (a ramp starts there)
    pending: list[tuple[PointResult, ModelParams]] = []
    for direction, indices in branches:
        for i in indices:
            if (key := unit_key(direction, i, 0)) in resume:
                info = resume[key]
                state = np.asarray(info["state"], dtype=np.float64) if info["ok"] else None
                kick_next = info["at_rest"]
                previous = config.values[i] if info["ok"] else None
                continue
            params = config.params_at(config.values[i])
            kicked = False
            if state is None:
                state = backend.initial_state(params, *config.initial)
            elif kick_next:
                state = backend.kick(state, config.kick)
                kicked = True
            ramp = config.ramp_params(previous, config.values[i]) if previous is not None else []
            state, failed = _ramp(backend, ramp, state)
            if failed is None:
                (run,), settled, used = run_units(
                    config, backend, [params], np.array([state]), one_by_one=True, ramped=len(ramp)
                )
            else:  # the ramp itself failed
                run, settled, used = failed, [False], [len(ramp)]
            result = PointResult(direction, i, 0, config.values[i], run, kicked, "", bool(settled[0]), int(used[0]))
            pending.append((result, params))
            if len(pending) == CLASSIFY_GROUP:
                yield from _classified(config, backend, pending)
                pending = []
            ok = run.status is Status.OK
            state = run.state if ok else None
            previous = config.values[i] if ok else None
            kick_next = ok and at_rest(run.records[:, REC_THETA_ABSMAX], config.rest_threshold)
    yield from _classified(config, backend, pending)


def _independent_units(config, backend, units, threads) -> list[UnitResult]:
    """Independent ``(point, start)`` units in one :meth:`~pendsweep.backends.Backend.run_points` call."""
    params, states, initials = [], [], {}
    for i, s in units:
        params.append(config.params_at(config.values[i]))
        if config.mode == "multistart" and i not in initials:
            initials[i] = multistart_initials(config, i)
        ic = initials[i][s] if config.mode == "multistart" else config.initial
        states.append(backend.initial_state(params[-1], *ic))
    runs, settled, used = run_units(config, backend, params, np.array(states), threads)
    motions = classify_runs(backend, params, runs, config.rest_threshold, config.evidence)
    return unit_results(
        [
            PointResult(
                "none",
                i,
                s,
                config.values[i],
                run,
                False,
                settled=bool(ok),
                transient_used=int(n),
                **classified_fields(motion, backend),
            )
            for (i, s), run, motion, ok, n in zip(units, runs, motions, settled, used)
        ],
        config.parameter,
        config.transient == "auto",
    )


def _independent_tasks(config, backend, finished: set[str], n_jobs, task_points) -> tuple[list[Callable], int]:
    """Tasks for the fresh/multistart units not yet done, and the local thread count for them.

    A batched backend (``backend.batched``) gets chunks of ``task_points``
    units cut from the full unit list in index order, each running on all
    ``n_jobs`` cores; a chunk with any unfinished unit is rerun whole, so a
    resumed unit is integrated beside the same neighbours as in an
    uninterrupted run. Otherwise there is one task per point (its
    unfinished starts), ``n_jobs`` at a time.
    """
    n_starts = config.starts if config.mode == "multistart" else 1
    units = [(i, s) for i in range(len(config.values)) for s in range(n_starts)]
    if backend.batched:
        threads = None if n_jobs < 1 else n_jobs
        task_points = max(task_points, backend.min_batch_points)
        chunks = [units[k : k + task_points] for k in range(0, len(units), task_points)]
        todo = [c for c in chunks if any(unit_key("none", i, s) not in finished for i, s in c)]
        return [functools.partial(_independent_units, config, backend, c, threads) for c in todo], 1
    tasks = []
    for i in range(len(config.values)):
        missing = [(i, s) for s in range(n_starts) if unit_key("none", i, s) not in finished]
        if missing:
            tasks.append(functools.partial(_independent_units, config, backend, missing, None))
    return tasks, n_jobs


def sweep_work(config: SweepConfig, backend) -> Work:
    """Integration steps of a sweep: units x (transient + record) periods x steps per period.

    Steps per period are averaged over up to 101 values spread over the range
    (they change only when ``fe`` is swept). Classification may add up to
    about 3x for points that are not periodic (extended record, Lyapunov pair).
    """
    steps = [backend.steps_per_period(config.params_at(config.values[i])) for i in sample_indices(len(config.values))]
    transient = config.max_transient_periods if config.transient == "auto" else config.transient_periods
    return Work(config.n_units, transient + config.record_periods, float(np.mean(steps)))


def sweep_metadata(config: SweepConfig) -> dict[str, Any]:
    meta = run_metadata("sweep", config.to_dict(), backend=config.backend, seed=config.seed)
    if config.backend_options.get("rig"):  # where a rig is reached is no part of what it measures: resumes may move
        from .rig_sweep import address_free_hash

        meta["config_hash"] = address_free_hash(meta["config"])
    return meta


@dataclass
class SweepScan:
    """A sweep as a :class:`pendsweep.engine.scan.Scan` (units ``direction:point:start``)."""

    config: SweepConfig
    task_points: int = 256
    #: A remote rig's continuous test: what it reports as it runs (:class:`pendsweep.studies.rig_sweep.RigWatch`).
    watch: Any = None
    #: The results file (a rig's time series goes beside it).
    output: Path | None = None
    row_columns: list[str] = field(default_factory=lambda: KEY_COLUMNS + ["period"])
    #: A resume reads back each finished unit's status and swing (:func:`~pendsweep.studies.sweep_rows.resume_info`).
    resume_columns: list[str] = field(default_factory=lambda: ["status", "theta_absmax"])

    def __post_init__(self) -> None:
        self.backend = self.config.make_backend()
        self.desc = self.config.parameter
        if not self.backend.restartable and self.config.mode == "continue":
            from .rig_sweep import default_watch

            self.watch = default_watch(self.watch, self.output)

    def metadata(self) -> dict[str, Any]:
        return sweep_metadata(self.config)

    def n_units(self) -> int:
        return self.config.n_units

    def work(self) -> Work:
        return sweep_work(self.config, self.backend)

    def tasks(self, finished: Finished, n_jobs: int) -> tuple[list[Callable], int]:
        config = self.config
        if not self.backend.restartable:
            n_jobs = 1  # its specimen serves one controller at a time
        if config.mode != "continue":
            return _independent_tasks(config, self.backend, finished.keys, n_jobs, self.task_points)
        resume = resume_info(finished.rows, finished.states, config.rest_threshold)
        if not self.backend.restartable:  # a remote rig: the whole test through one connection
            from .rig_sweep import rig_test

            emulated = run_sweep(config.emulated_reference(), as_frame=False) if self.watch.reference else None
            return [functools.partial(rig_test, config, self.backend, resume, self.watch, finished.rows, emulated)], 1
        walks = [config.branches()] if config.direction == "loop" else [[branch] for branch in config.branches()]
        return [functools.partial(_continue_branches, config, self.backend, walk, resume) for walk in walks], n_jobs

    def order(self, df: pd.DataFrame) -> pd.DataFrame:
        return df.sort_values(self.row_columns, kind="stable").reset_index(drop=True)


def run_sweep(
    config: SweepConfig,
    output: Path | None = None,
    *,
    n_jobs: int = 1,
    progress: bool = False,
    overwrite: bool = False,
    executor: Executor | None = None,
    task_points: int = 256,
    max_work: float | None = DEFAULT_MAX_WORK,
    as_frame: bool = True,
    checkpoint_seconds: float = 1.0,
    watch: Any = None,
) -> pd.DataFrame | pa.Table:
    """Run (or resume) a sweep and return its long-form results.

    Parameters
    ----------
    config : SweepConfig
    output : Path, optional
        Parquet file. When given, finished points are persisted as they come
        and a rerun with the same configuration resumes; without it results
        are only returned.
    n_jobs : int
        Parallel workers for independent branches or points (-1: all cores).
    progress : bool
        Show a progress bar (points done, rate, ETA) on stderr.
    overwrite : bool
        Discard earlier results at ``output`` instead of resuming.
    executor : Executor, optional
        Where tasks run (:mod:`pendsweep.engine.executors`; default: this process).
        Fresh and multistart points on a batched backend go in tasks of
        ``task_points`` points; a continue branch is one task.
    max_work : float or None
        Refuse the sweep (``ConfigError``) when its estimate (:func:`sweep_work`)
        exceeds this many integration steps; None: no limit.
    as_frame : bool
        False: return a pyarrow Table (same rows and order) instead of a
        DataFrame, as the command line does.
    checkpoint_seconds : float
        With ``output``: a finished unit (a point, or a continue branch's
        point) is written to the parts directory at most this many seconds
        after it finishes (0: at once); a killed sweep resumes from there.
    watch : RigWatch, optional
        A remote rig's continuous test (continue mode): where its time
        series goes, its live plot, its safe stop and its per-point lines
        (:class:`pendsweep.studies.rig_sweep.RigWatch`; default: the time
        series beside ``output``, lines on stderr).

    Returns
    -------
    pandas.DataFrame
        One row per (direction, point, start, period), sorted; columns are
        documented in the README.
    """
    scan = SweepScan(config, task_points, watch=watch, output=output)
    return run_scan(
        scan,
        output,
        n_jobs=n_jobs,
        progress=progress,
        overwrite=overwrite,
        executor=executor,
        max_work=max_work,
        as_frame=as_frame,
        checkpoint_seconds=checkpoint_seconds if scan.backend.restartable else 0.0,  # a rig test's points: at once
    )
