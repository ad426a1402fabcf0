"""Basin scans as configured, resumable runs persisted like sweeps (:class:`BasinConfig`, :func:`run_basins`)."""

from __future__ import annotations

import abc
import functools
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ...analysis.attractors import (
    MATCH_TOL,
    ROTATION_WINDOW,
    SETTLE_TOL,
    SETTLE_WINDOW,
)
from ...analysis.sections import MAX_PERIOD
from ...backends.status import Status
from ...errors import ConfigError
from ...model.params import ModelParams

if TYPE_CHECKING:  # pandas (0.3 s) is imported by the functions that build frames, not by importing this module
    import pandas as pd
from .rounds import (
    _STATUS_CODE,
    CHUNK_STARTS,
    NOISY_SETTLE_TOL,
    ROUND_PERIODS,
    BackendMap,
    EmulatedMap,
    SettledRuns,
    StroboscopicMap,
    settle_runs,
)

SAMPLINGS = ("random", "grid")


@dataclass(frozen=True)
class BasinConfig:
    """Everything that determines a basin run (stored in every result file).

    Attributes
    ----------
    parameter : str
        Model parameter held at each of ``values`` (one value: a single basin).
    values : tuple of float
        Parameter values, ascending.
    model : dict
        Overrides of the default :class:`~pendsweep.model.params.ModelParams`.
    sampling : {"random", "grid"}
        ``random``: ``samples`` starts drawn from ``default_rng([seed, point])``
        exactly as multistart sweeps draw theta and thetadot (sample i is
        multistart start i + 1); ``grid``: a cell-centred ``grid`` of
        (theta, thetadot) starts (symmetric ranges give a grid symmetric
        about 0 that avoids theta = +-pi).
    theta_range : (float, float)
        Initial theta interval [rad] (default (-pi, pi]).
    thetadot_range : (float, float) or None
        Initial thetadot interval [rad/s]; None: (-w_p, w_p) at each point.
    max_periods : int
        Cap on forcing periods per start.
    round_periods : int
        Periods between settling checks.
    tol : float, optional
        Settling tolerance [normalised, ~rad]. Default
        :data:`~pendsweep.analysis.attractors.SETTLE_TOL` (1e-3) on the emulated
        backend and :data:`NOISY_SETTLE_TOL` on others, whose sections carry
        sensor noise and encoder quantisation (one pulse is 1.3e-3 rad).
    backend, backend_options
        Registered backend and its options; ``emulated`` runs on the batched
        kernel, others one start at a time with per-start noise seeds.
    """

    parameter: str
    values: tuple[float, ...]
    model: dict[str, float] = field(default_factory=dict)
    sampling: str = "random"
    samples: int = 1000
    grid: tuple[int, int] = (100, 100)
    seed: int = 0
    theta_range: tuple[float, float] = (-math.pi, math.pi)
    thetadot_range: tuple[float, float] | None = None
    max_periods: int = 1000
    round_periods: int = ROUND_PERIODS
    tol: float | None = None
    backend: str = "emulated"
    backend_options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (isinstance(self.seed, int) and 0 <= self.seed < 2**63):
            raise ConfigError(f"seed = {self.seed!r} must be an integer in [0, 2**63) (numpy's seed sequences)")
        if self.tol is None:
            object.__setattr__(self, "tol", SETTLE_TOL if self.backend == "emulated" else NOISY_SETTLE_TOL)
        if not (math.isfinite(self.tol) and 0 < self.tol < MATCH_TOL):
            raise ConfigError(f"tol = {self.tol!r} must lie in (0, {MATCH_TOL:g}) (normalised section units, ~rad)")
        from ...model.params import PARAM_SPECS, check_value

        if self.parameter not in PARAM_SPECS:
            raise ConfigError(f"unknown parameter {self.parameter!r}; known: {', '.join(PARAM_SPECS)}")
        if not self.values:
            raise ConfigError("a basin run needs at least one parameter value")
        object.__setattr__(self, "values", tuple(sorted(check_value(self.parameter, float(v)) for v in self.values)))
        if self.sampling not in SAMPLINGS:
            raise ConfigError(f"sampling = {self.sampling!r}; choose one of {', '.join(SAMPLINGS)}")
        object.__setattr__(self, "grid", tuple(int(g) for g in self.grid))
        for name, v, lo in (  # named as the command line spells them
            ("--starts", self.samples, 1),
            ("--grid (theta)", self.grid[0], 1),
            ("--grid (thetadot)", self.grid[1], 1),
            ("--max-periods", self.max_periods, SETTLE_WINDOW),
            ("round_periods", self.round_periods, 1),
        ):
            if int(v) != v or v < lo:
                raise ConfigError(f"{name} = {v!r} must be an integer >= {lo}")
        ranges = [("theta", self.theta_range)] + ([("thetadot", self.thetadot_range)] if self.thetadot_range else [])
        for name, r in ranges:
            if len(r) != 2 or not all(math.isfinite(x) for x in r) or not r[0] < r[1]:
                raise ConfigError(f"{name} range {r!r} must be two finite numbers A < B")
        for v in self.values:
            self.params_at(v)
        self.make_backend().validate(self.params_at(self.values[0]))

    @property
    def starts(self) -> int:
        return self.samples if self.sampling == "random" else self.grid[0] * self.grid[1]

    def params_at(self, value: float) -> ModelParams:
        return ModelParams.from_mapping(self.model).replace(**{self.parameter: value})

    def make_backend(self):
        from ...backends import make_backend

        return make_backend(self.backend, **self.backend_options)

    def initial_conditions(self, point: int) -> tuple[np.ndarray, np.ndarray]:
        """``(theta0 [rad], thetadot0 [rad/s])``, each ``(starts,)``, of one point (y = ydot = 0)."""
        wp = self.params_at(self.values[point]).omega_p
        (ta, tb), (da, db) = self.theta_range, self.thetadot_range or (-wp, wp)
        if self.sampling == "random":
            rng = np.random.default_rng([self.seed, point])
            n = self.samples
            return tb - (tb - ta) * rng.random(n), da + (db - da) * rng.random(n)
        nt, nd = self.grid
        theta = ta + (tb - ta) * (np.arange(nt) + 0.5) / nt
        thetadot = da + (db - da) * (np.arange(nd) + 0.5) / nd
        tt, dd = np.meshgrid(theta, thetadot, indexing="ij")
        return tt.ravel(), dd.ravel()

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["values"] = list(self.values)
        d["grid"] = list(self.grid)
        d["theta_range"] = list(self.theta_range)
        d["thetadot_range"] = None if self.thetadot_range is None else list(self.thetadot_range)
        d["model"] = ModelParams.from_mapping(self.model).to_dict()
        d["backend_options"] = self.make_backend().options()
        d["settle"] = {
            "window": SETTLE_WINDOW,
            "max_period": MAX_PERIOD,
            "match_tol": MATCH_TOL,
            "rotation_window": ROTATION_WINDOW,
        }
        return d


ROW_COLUMNS = ["point", "start"]


def system_for(config: BasinConfig, point: int, workers: int) -> StroboscopicMap:
    """The stroboscopic map of one parameter point on the configured backend."""
    backend = config.make_backend()
    params = config.params_at(config.values[point])
    if backend.name == "emulated":
        return EmulatedMap((params,), backend.dt, backend.signum, device=backend.device, precision=backend.precision)
    return BackendMap(backend, params, (config.seed, point), workers)


def runs_frame(config: BasinConfig, point: int, starts: np.ndarray, runs: SettledRuns) -> pd.DataFrame:
    """One row per start: its initial condition and outcome (cycle as a 32-float list, NaN-padded)."""
    theta0, thetadot0 = config.initial_conditions(point)
    import pandas as pd

    df = pd.DataFrame(
        {
            config.parameter: config.values[point],
            "point": np.int64(point),
            "start": starts.astype(np.int64),
            "theta0": theta0[starts],
            "thetadot0": thetadot0[starts],
            "status": [Status.from_code(c).value for c in runs.status],
            "motion": runs.motion.astype(str),
            "period": runs.period,
            "rotation_number": runs.turns / np.maximum(runs.period, 1),
            "turns": runs.turns,
            "settle_periods": runs.settle_periods,
            "escape_periods": runs.escape_periods,
            "periods_done": runs.periods_done,
            "theta_absmax": runs.theta_absmax,
        }
    )
    df["cycle"] = list(runs.cycle.reshape(len(starts), -1))
    df["scales"] = list(runs.scales)
    return df


def runs_from_frame(df: pd.DataFrame) -> SettledRuns:
    """Rebuild :class:`SettledRuns` from stored rows (for summaries of finished or resumed runs)."""
    k = len(df)
    status = np.array([_STATUS_CODE[Status(s)] for s in df["status"]], dtype=np.int64)
    motion = df["motion"].to_numpy().astype(str)
    settled = ~np.isin(motion, ["unsettled", "n/a"])
    return SettledRuns(
        status=status,
        settled=settled,
        period=df["period"].to_numpy(np.int64),
        turns=df["turns"].to_numpy(np.int64),
        at_rest=motion == "semi-trivial",
        settle_periods=df["settle_periods"].to_numpy(np.int64),
        escape_periods=df["escape_periods"].to_numpy(np.int64),
        periods_done=df["periods_done"].to_numpy(np.int64),
        cycle=np.stack(df["cycle"].to_numpy()).reshape(k, MAX_PERIOD, 4) if k else np.empty((0, MAX_PERIOD, 4)),
        scales=np.stack(df["scales"].to_numpy()) if k else np.empty((0, 4)),
        theta_absmax=df["theta_absmax"].to_numpy(float),
        states=np.empty((k, 0)),
    )


def _basin_task(config: BasinConfig, point: int, starts: np.ndarray, workers: int) -> list:
    from ...engine.scan import UnitResult

    params = config.params_at(config.values[point])
    theta0, thetadot0 = config.initial_conditions(point)
    backend = config.make_backend()
    states = np.stack([backend.initial_state(params, 0.0, 0.0, theta0[s], thetadot0[s]) for s in starts])
    system = system_for(config, point, workers)
    runs = settle_runs(
        system, states, config.max_periods, ids=starts, round_periods=config.round_periods, tol=config.tol
    )
    return [UnitResult(unit_key(point, int(starts[0])), runs_frame(config, point, starts, runs))]


def unit_key(point: int, first_start: int) -> str:
    """Key of one unit of a basin scan: the chunk of starts of ``point`` beginning at ``first_start``."""
    return f"{int(point)}:{int(first_start)}"


def chunk_ranges(n: int, size: int) -> list[np.ndarray]:
    """``range(n)`` in consecutive chunks of ``size`` indices (the last one shorter)."""
    return [np.arange(first, min(first + size, n)) for first in range(0, n, size)]


class SettleScan(abc.ABC):
    """The scan contract (:class:`pendsweep.engine.scan.Scan`) shared by basins and maps.

    Their units are chunks of independent starts, each run settled in rounds
    (:func:`settle_runs`) and stored as one row per start; a resume needs
    only the finished keys. A subclass has ``config`` (with ``max_periods``)
    and ``row_columns``, and gives

    1. :meth:`chunks`: the units as ``[(key, payload)]``, in order;
    2. :meth:`unit_task`: the callable that runs one unit's payload;
    3. :meth:`starts` and :meth:`steps_per_period`: starts in all, and steps per
       forcing period averaged over the study (for the work estimate).
    """

    resume_columns: list[str] = []

    @abc.abstractmethod
    def chunks(self) -> list[tuple[str, Any]]:
        """The units, ``[(key, payload)]`` in order."""

    @abc.abstractmethod
    def unit_task(self, payload: Any, n_jobs: int):
        """The zero-argument callable that runs one unit's ``payload``, returning its ``UnitResult`` list."""

    @abc.abstractmethod
    def starts(self) -> int:
        """Starts in all (grid cells, or points x starts)."""

    @abc.abstractmethod
    def steps_per_period(self) -> float:
        """Integration steps per forcing period, averaged over the study."""

    def n_units(self) -> int:
        return len(self.chunks())

    def work(self):
        """Upper bound: every start integrated to the cap (early stop typically does 10-30 % of it).

        Its results take about :data:`~pendsweep.engine.scan.RESULT_ROW_BYTES` per start when gathered.
        """
        from ...engine.scan import RESULT_ROW_BYTES, Work

        starts = self.starts()
        return Work(starts, self.config.max_periods, self.steps_per_period(), result_bytes=starts * RESULT_ROW_BYTES)

    def tasks(self, finished, n_jobs: int):
        from ...engine.scan import check_unit_keys

        chunks = self.chunks()
        check_unit_keys(finished, {key for key, _ in chunks})
        # A unit runs the batched kernel on every core (or its starts on n_jobs threads): one unit at a time locally.
        return [self.unit_task(payload, n_jobs) for key, payload in chunks if key not in finished.keys], 1

    def order(self, df: pd.DataFrame) -> pd.DataFrame:
        return df.sort_values(self.row_columns, kind="stable").reset_index(drop=True)


@dataclass
class BasinScan(SettleScan):
    """A basin computation as a scan: one unit per chunk of starts of one point."""

    config: BasinConfig
    chunk_starts: int = CHUNK_STARTS
    desc: str = "basins"
    row_columns: list[str] = field(default_factory=lambda: list(ROW_COLUMNS))

    def metadata(self) -> dict[str, Any]:
        from ...engine.results import run_metadata

        return run_metadata("basins", self.config.to_dict(), backend=self.config.backend, seed=self.config.seed)

    def chunks(self) -> list[tuple[str, tuple[int, np.ndarray]]]:
        # A GPU needs ~1e5 threads to be busy: its units hold at least the backend's minimum batch.
        size = max(self.chunk_starts, self.config.make_backend().min_batch_points)
        return [
            (unit_key(point, int(starts[0])), (point, starts))
            for point in range(len(self.config.values))
            for starts in chunk_ranges(self.config.starts, size)
        ]

    def unit_task(self, payload: tuple[int, np.ndarray], n_jobs: int):
        workers = (os.cpu_count() or 1) if n_jobs < 1 else n_jobs
        return functools.partial(_basin_task, self.config, *payload, workers)

    def starts(self) -> int:
        return len(self.config.values) * self.config.starts

    def steps_per_period(self) -> float:
        from ...backends import steps_per_period

        dt = self.config.make_backend().options().get("dt", 1e-3)
        return float(np.mean([steps_per_period(self.config.params_at(v).fe, dt) for v in self.config.values]))


def run_basins(
    config: BasinConfig,
    output: Path | None = None,
    *,
    n_jobs: int = -1,
    progress: bool = False,
    overwrite: bool = False,
    executor=None,
    chunk_starts: int = CHUNK_STARTS,
    max_work: float | None = None,
    checkpoint_seconds: float = 1.0,
    return_rows: bool = True,
) -> pd.DataFrame | None:
    """Run (or resume) a basin computation; return one row per (point, start).

    Starts go in units of ``chunk_starts`` (one parameter point each; at
    least :data:`pendsweep.backends.gpu.GPU_BATCH_POINTS` on a GPU), run
    by the scan engine (:func:`pendsweep.engine.scan.run_scan`): a finished unit is
    persisted through :class:`~pendsweep.engine.results.ResultStore` at most
    ``checkpoint_seconds`` s after it finishes, so a rerun of the same configuration skips it. On the emulated backend a
    unit runs the batched kernel on all cores (units one after another
    locally, in parallel on Dask); on other backends a unit's starts run on
    ``n_jobs`` threads. ``max_work`` limits the work estimate, an upper
    bound (every start to the cap); None: no limit. ``return_rows=False``
    (with ``output``): return None and never hold all rows (read the columns
    needed back from ``output``).
    """
    from ...engine.scan import run_scan

    scan = BasinScan(config, chunk_starts)
    return run_scan(
        scan,
        output,
        n_jobs=n_jobs,
        progress=progress,
        overwrite=overwrite,
        executor=executor,
        max_work=max_work,
        checkpoint_seconds=checkpoint_seconds,
        return_rows=return_rows,
    )
