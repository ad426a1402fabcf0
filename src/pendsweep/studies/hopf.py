"""Hopf boundary of the semi-trivial solution, alpha_H(omega_hat, M), three ways.

The semi-trivial solution is the pendulum at rest (theta = 0) while the
oscillator is driven, ``(M + m) y'' + C y' + K y = alpha sin(w_e t)``. Near
``w_e = 2 w_p`` it loses stability to a pendulum swinging at ``w_e / 2``;
the forcing amplitude where this happens, as a function of
``omega_hat = w_e / (2 w_p)``, is the boundary of Fig. 10 of the paper.

Methods
-------
``analytic``
    Eq. (12) of the paper, from small-angle averaging with ``b1 = b3 = 0``:
    ``alpha_H = l w_e^2 (M + m) sqrt((kappa/w_e)^2 + sigma^2) sqrt((kappa_p/w_e)^2 + sigma_p^2)``
    with ``kappa = C/(M + m)``, ``kappa_p = b2/(m l^2)``,
    ``sigma = (w_nm/w_e)^2 - 1``, ``sigma_p = 2[(w_p/w_e)^2 - 1/4]``.
``floquet``
    The linearised pendulum about the exact semi-trivial solution is the
    damped Mathieu equation ``theta'' + kappa_p theta' + (w_p^2 + y''(t)/l) theta = 0``
    whose pump ``y''(t)`` is the exact steady response of the linear
    oscillator. Its monodromy matrix over one forcing period is integrated
    (RK4, coefficients exact at the stage times) and ``alpha_H`` is the
    smallest alpha where the largest Floquet multiplier modulus crosses 1
    (brentq on ``log max|mu|``). This is exact for the smooth model
    (``b1 = 0``); ``b3 theta'^2`` has no linear part and does not enter.
    Coulomb friction ``b1`` cannot be linearised (it makes rest "sticky")
    and is ignored by both linear methods.
``simulate``
    The paper's experimental protocol on any registered backend: at a trial
    alpha the oscillator is settled on its semi-trivial response with the
    pendulum at rest, the pendulum is kicked by ``kick`` rad, and the
    per-period envelope max|theta| is recorded for ``periods`` forcing
    periods. The growth rate is the least-squares slope of ``log`` envelope
    against period number; alpha is *above* the boundary when it is positive
    (or the pendulum rotates). Bisection on alpha brackets the boundary to
    ``tol`` N.

Why a long, fitted window: the pendulum's viscous decay is tiny
(``kappa_p T ~ 2e-3`` per period), so just below the boundary the two
Floquet multipliers are a nearly degenerate complex pair and a kicked
pendulum *beats*, its envelope rising 10-50 times over 50-200 periods before
falling back. Judging "moving or not" over a short record, or by a threshold
on the amplitude, puts the boundary too low; the log-envelope slope over a
window several beat periods long (600 periods by default) is negative below
and positive above, because the true rates are ``-kappa_p T / 2`` and
``log|mu| > 0`` respectively.

With Coulomb friction (``b1 > 0``) rest is locally stable at any alpha, so
the simulated boundary depends on the kick; the kick is stored with every
row.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from ..analysis.hopf_protocol import hopf_simulate, hopf_simulate_many
from ..analysis.semi_trivial import (
    alpha_hopf_analytic,
    fe_for_omega_hat,
    floquet_multipliers,
    hopf_floquet,
    semi_trivial_response,
)
from ..backends import make_backend
from ..backends.status import Status
from ..engine.columns import repeated, table
from ..engine.executors import Executor
from ..engine.results import run_metadata
from ..engine.scan import DEFAULT_MAX_WORK, RESULT_ROW_BYTES, Finished, UnitResult, Work, run_scan, sample_indices
from ..errors import ConfigError
from ..model.params import ENCODER_RESOLUTION, ModelParams, check_value

#: The Hopf API: the scans here, the methods from :mod:`.semi_trivial` and :mod:`.hopf_protocol`.
__all__ = [
    "ANALYTIC_CHUNK", "COLUMNS", "METHODS", "HopfConfig", "HopfScan", "alpha_hopf_analytic", "fe_for_omega_hat",
    "floquet_multipliers", "hopf_analytic_rows", "hopf_floquet", "hopf_metadata", "hopf_point", "hopf_simulate",
    "hopf_simulate_rows", "run_hopf", "semi_trivial_response",
]  # fmt: skip

METHODS = ("analytic", "floquet", "simulate")
#: Longer even grids of omega_hat are stored in the metadata as ``{"linspace": [first, last, n]}``.
LINSPACE_MIN = 16
#: Points of one unit of the closed form, Eq. (12), evaluated at once (a million values: 16 units).
ANALYTIC_CHUNK = 65536
KEY_COLUMNS = ["mass_point", "point", "method"]
#: Columns of a Hopf scan result, in order.
COLUMNS = [
    "omega_hat",
    "fe",
    "M",
    "method",
    "alpha_H",
    "status",
    "multiplier",
    "growth_below",
    "growth_above",
    "bracket_lo",
    "bracket_hi",
    "kick",
    "runs",
    "backend",
]


# -- scans ------------------------------------------------------------------------
#: Monodromy evaluations of one Floquet row, about (grid from 1e-3 N by 1.2x to alpha_H, then brentq).
FLOQUET_EVALUATIONS = 100
#: Simulate rows per task when the backend has a batched kernel (bisections run in lockstep).
SIMULATE_TASK_ROWS = 64


@dataclass(frozen=True)
class HopfConfig:
    """A Hopf-boundary scan over (omega_hat, M, method); stored with every result file.

    Attributes
    ----------
    omega_hat : tuple of float
        Frequency ratios w_e / (2 w_p) (> 0); ``fe = omega_hat w_p / pi``.
    masses : tuple of float
        Oscillator masses M [kg].
    methods : tuple of str
        Any of ``analytic``, ``floquet``, ``simulate``.
    model : dict
        Overrides of the default :class:`~pendsweep.model.params.ModelParams`.
    backend, backend_options
        Backend of the ``simulate`` method (any registered name).
    kick : float
        Pendulum perturbation [rad] of the simulate method.
    periods, settle_periods : int
        Envelope record after the kick, and oscillator settling before it [forcing periods].
    tol : float
        Bisection stops when the bracket is narrower than this [N].
    alpha_max : float
        Give up (status ``not-found``) above this amplitude [N].
    floquet_steps : int
        RK4 steps per period of the monodromy integration.
    rest_threshold : float
        Simulate: the kicked pendulum is "at rest" when its last period's
        max |theta| is below this [rad] (one encoder pulse by default).
    """

    omega_hat: tuple[float, ...]
    masses: tuple[float, ...] = (10.9,)
    methods: tuple[str, ...] = METHODS
    model: dict[str, float] = field(default_factory=dict)
    backend: str = "emulated"
    backend_options: dict[str, Any] = field(default_factory=dict)
    kick: float = 0.01
    periods: int = 200
    settle_periods: int = 10
    tol: float = 0.1
    alpha_max: float = 500.0
    floquet_steps: int = 200
    rest_threshold: float = ENCODER_RESOLUTION

    def __post_init__(self) -> None:
        for name in ("omega_hat", "masses", "methods"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
            if not getattr(self, name):
                raise ConfigError(f"a Hopf scan needs at least one value of {name}")
        w = self.omega_hat_array
        bad_w = ~(np.isfinite(w) & (w > 0))
        if bad_w.any():
            raise ConfigError(f"omega_hat = {self.omega_hat[int(np.argmax(bad_w))]!r} must be a finite number > 0")
        object.__setattr__(self, "masses", tuple(check_value("M", v) for v in self.masses))
        bad = [m for m in self.methods if m not in METHODS]
        if bad:
            raise ConfigError(f"unknown Hopf method(s) {', '.join(bad)}; choose from {', '.join(METHODS)}")
        twice = sorted({m for m in self.methods if self.methods.count(m) > 1})
        if twice:
            raise ConfigError(f"--method lists {', '.join(twice)} twice; give each method once")
        for name, lo in (("periods", 2), ("settle_periods", 0), ("floquet_steps", 8)):
            v = getattr(self, name)
            if int(v) != v or v < lo:
                raise ConfigError(f"{name} = {v!r} must be an integer >= {lo}")
        for name in ("kick", "tol", "alpha_max"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{name} = {v!r} must be a finite number > 0")
        if not (math.isfinite(self.rest_threshold) and self.rest_threshold >= 0):
            raise ConfigError(f"rest_threshold = {self.rest_threshold!r} rad must be a finite number >= 0")
        backend = make_backend(self.backend, **self.backend_options)
        # The checks are monotone in fe and M (fe above 1/dt, M above M2, fe inside a filter
        # band), so the extreme frequencies and masses stand for every point.
        for i in {int(np.argmin(self.omega_hat)), int(np.argmax(self.omega_hat))}:
            for j in {int(np.argmin(self.masses)), int(np.argmax(self.masses))}:
                params = self.params_at(i, j)
                semi_trivial_response(params)
                if "simulate" in self.methods:
                    backend.validate(params)

    @functools.cached_property
    def omega_hat_array(self) -> np.ndarray:
        """``omega_hat`` as a float64 array, converted once (a million-value tuple takes 20 ms each time)."""
        return np.asarray(self.omega_hat, dtype=np.float64)

    def params_at(self, point: int, mass_point: int) -> ModelParams:
        base = ModelParams.from_mapping(self.model).replace(M=self.masses[mass_point])
        return base.replace(fe=fe_for_omega_hat(base, self.omega_hat[point]))

    def units(self) -> list[tuple[int, int, str]]:
        """Every ``(mass_point, point, method)`` of the scan.

        The closed form is evaluated for :data:`ANALYTIC_CHUNK` points at once:
        its unit is ``(mass_point, first point of the chunk, "analytic")``.
        """
        n = len(self.omega_hat)
        return [
            (j, i, method)
            for j in range(len(self.masses))
            for method in self.methods
            for i in (range(0, n, ANALYTIC_CHUNK) if method == "analytic" else range(n))
        ]

    def to_dict(self) -> dict[str, Any]:
        # a shallow copy: dataclasses.asdict deep-copies every value (5 s for a million omega_hat)
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["backend_options"] = dict(d["backend_options"])
        for name in ("omega_hat", "masses", "methods"):
            d[name] = list(d[name])
        w = self.omega_hat_array
        if w.size > LINSPACE_MIN and np.array_equal(w, np.linspace(w[0], w[-1], w.size)):
            # an even grid, exactly: stored as its three numbers (a million values are 20 MB of JSON)
            d["omega_hat"] = {"linspace": [float(w[0]), float(w[-1]), int(w.size)]}
        d["model"] = ModelParams.from_mapping(self.model).to_dict()
        d["backend_options"] = make_backend(self.backend, **self.backend_options).options()
        return d


def hopf_analytic_rows(config: HopfConfig, mass_point: int, first: int) -> pa.Table:
    """The ``analytic`` rows of the chunk of points from ``first`` (Eq. (12), vectorised).

    Built as Arrow columns straight from numpy (:mod:`pendsweep.engine.columns`): a
    pandas frame per chunk cost more than the formula (0.6 s for a million).
    """
    points = np.arange(first, min(first + ANALYTIC_CHUNK, len(config.omega_hat)), dtype=np.int64)
    base = config.params_at(first, mass_point)
    omega_hat = config.omega_hat_array[points]
    fe = omega_hat * base.omega_p / math.pi  # fe_for_omega_hat, for every point at once
    n = points.size
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is a row status, not a warning
        alpha_h = np.asarray(alpha_hopf_analytic(base, 2.0 * math.pi * fe), dtype=np.float64)
    values: dict[str, Any] = {name: np.full(n, math.nan) for name in COLUMNS}
    values.update(
        omega_hat=omega_hat, fe=fe, M=np.full(n, base.M), method=repeated("analytic", n),
        alpha_H=alpha_h, status=_analytic_status(alpha_h),
        runs=np.ones(n, dtype=np.int64), backend=repeated("", n),
    )  # fmt: skip
    return table(
        {"mass_point": np.full(n, mass_point, dtype=np.int64), "point": points} | {c: values[c] for c in COLUMNS}
    )


def _analytic_status(alpha_h: np.ndarray):
    """``ok`` rows, and ``diverged`` where Eq. (12) overflowed (extreme omega_hat or M): an Arrow string column."""
    import pyarrow as pa

    if np.all(np.isfinite(alpha_h)):
        return repeated("ok", alpha_h.size)
    return pa.array(np.where(np.isfinite(alpha_h), "ok", Status.DIVERGED.value).tolist(), pa.string())


def hopf_point(config: HopfConfig, mass_point: int, point: int, method: str, backend=None) -> pd.DataFrame:
    """One result row (as a one-row DataFrame with :data:`COLUMNS` and the keys); ``analytic``: its chunk."""
    params = config.params_at(point, mass_point)
    if method == "analytic":
        return hopf_analytic_rows(config, mass_point, point)
    if method == "floquet":
        return _result_row(
            config, mass_point, point, method, hopf_floquet(params, config.floquet_steps, config.alpha_max)
        )
    return hopf_simulate_rows(config, [(mass_point, point)], backend)[0]


def hopf_simulate_rows(config: HopfConfig, points: list[tuple[int, int]], backend=None) -> list[pd.DataFrame]:
    """The ``simulate`` rows of ``(mass_point, point)`` pairs, bisected in lockstep (:func:`hopf_simulate_many`)."""
    backend = backend or make_backend(config.backend, **config.backend_options)
    results = hopf_simulate_many(
        [config.params_at(i, j) for j, i in points],
        backend,
        kick=config.kick,
        periods=config.periods,
        settle_periods=config.settle_periods,
        tol=config.tol,
        alpha_max=config.alpha_max,
        rest_threshold=config.rest_threshold,
    )
    return [
        _result_row(config, j, i, "simulate", dict(r, kick=config.kick, backend=config.backend))
        for (j, i), r in zip(points, results)
    ]


def _result_row(config: HopfConfig, mass_point: int, point: int, method: str, result: dict[str, Any]) -> pd.DataFrame:
    params = config.params_at(point, mass_point)
    row: dict[str, Any] = dict(
        omega_hat=config.omega_hat[point],
        fe=params.fe,
        M=params.M,
        method=method,
        alpha_H=math.nan,
        status="ok",
        multiplier=math.nan,
        growth_below=math.nan,
        growth_above=math.nan,
        bracket_lo=math.nan,
        bracket_hi=math.nan,
        kick=math.nan,
        runs=1,
        backend="",
    )
    row.update(result)
    df = pd.DataFrame([row], columns=COLUMNS)
    df.insert(0, "mass_point", np.int64(mass_point))
    df.insert(1, "point", np.int64(point))
    df["runs"] = df["runs"].astype(np.int64)
    return df


def hopf_metadata(config: HopfConfig) -> dict[str, Any]:
    return run_metadata("hopf", config.to_dict(), backend=config.backend)


def _unit_key(mass_point: int, point: int, method: str) -> str:
    return f"{int(mass_point)}:{int(point)}:{method}"


def _units(blocks: list[pd.DataFrame | pa.Table]) -> list[UnitResult]:
    """Each block of rows as one unit, keyed by its first row."""
    return [UnitResult(_unit_key(*_first_key(rows)), rows) for rows in blocks]


def _first_key(rows: pd.DataFrame | pa.Table) -> list:
    if isinstance(rows, pa.Table):
        return [rows[k][0].as_py() for k in KEY_COLUMNS]
    return list(rows.iloc[0][KEY_COLUMNS])


def _simulate_task(config: HopfConfig, points: list[tuple[int, int]], backend) -> list[UnitResult]:
    return _units(hopf_simulate_rows(config, points, backend))


def _point_task(config: HopfConfig, mass_point: int, point: int, method: str, backend) -> list[UnitResult]:
    return _units([hopf_point(config, mass_point, point, method, backend=backend)])


@dataclass
class HopfScan:
    """A Hopf scan as a :class:`pendsweep.engine.scan.Scan` (units ``mass_point:point:method``)."""

    config: HopfConfig
    desc: str = "hopf"
    row_columns: list[str] = field(default_factory=lambda: list(KEY_COLUMNS))
    resume_columns: list[str] = field(default_factory=list)  # a resume needs only the finished keys

    def __post_init__(self) -> None:
        self.backend = make_backend(self.config.backend, **self.config.backend_options)

    def metadata(self) -> dict[str, Any]:
        return hopf_metadata(self.config)

    def n_units(self) -> int:
        return len(self.config.units())

    def work(self) -> Work:
        """Integration steps: simulate points x trial amplitudes x (settle + record) periods x steps.

        Trial amplitudes are bounded by doubling from the first guess up to
        ``alpha_max`` plus bisecting down to ``tol``; Floquet rows count
        their monodromy steps (:data:`FLOQUET_EVALUATIONS` of ``floquet_steps`` each).
        """
        config = self.config
        n_points = len(config.omega_hat) * len(config.masses)
        runs = math.ceil(math.log2(config.alpha_max / config.tol)) + 2
        sample = [
            config.params_at(i, j)
            for i in sample_indices(len(config.omega_hat))
            for j in sample_indices(len(config.masses), 11)
        ]
        steps = float(np.mean([self.backend.steps_per_period(q) for q in sample]))
        simulate = n_points * runs if "simulate" in config.methods else 0
        floquet = n_points * FLOQUET_EVALUATIONS * config.floquet_steps if "floquet" in config.methods else 0
        # Every row is held when the scan is gathered and ordered (Arrow, then the frame): the memory
        # check refuses a closed-form scan of 10^8 rows before it starts.
        rows = n_points * len(config.methods)
        return Work(
            simulate, config.settle_periods + config.periods, steps, other=floquet, result_bytes=rows * RESULT_ROW_BYTES
        )

    def tasks(self, finished: Finished, n_jobs: int) -> tuple[list[Callable], int]:
        """Analytic and Floquet rows one task each; simulate rows of a batched backend in chunks.

        The chunks of :data:`SIMULATE_TASK_ROWS` points are cut from all
        simulate points in index order, and a chunk with any unfinished row
        is rerun whole, so its lockstep bisections share every kernel call
        with the same neighbours as in an uninterrupted run.
        """
        config, backend, done = self.config, self.backend, finished.keys
        batched = [(j, i) for j, i, method in config.units() if method == "simulate" and backend.batched]
        chunks = [batched[k : k + SIMULATE_TASK_ROWS] for k in range(0, len(batched), SIMULATE_TASK_ROWS)]
        tasks: list[Callable] = [
            functools.partial(_simulate_task, config, chunk, backend)
            for chunk in chunks
            if any(_unit_key(j, i, "simulate") not in done for j, i in chunk)
        ]
        in_batches = set(batched)
        tasks += [
            functools.partial(_point_task, config, j, i, method, backend)
            for j, i, method in config.units()
            if _unit_key(j, i, method) not in done and (method != "simulate" or (j, i) not in in_batches)
        ]
        return tasks, n_jobs

    def order(self, df: pd.DataFrame) -> pd.DataFrame:
        return _ordered(df, self.config)


def run_hopf(
    config: HopfConfig,
    output: Path | None = None,
    *,
    n_jobs: int = 1,
    progress: bool = False,
    overwrite: bool = False,
    executor: Executor | None = None,
    max_work: float | None = DEFAULT_MAX_WORK,
    checkpoint_seconds: float = 1.0,
    return_rows: bool = True,
) -> pd.DataFrame | None:
    """Run (or resume) a Hopf-boundary scan; one row per (M, omega_hat, method).

    ``executor`` (:mod:`pendsweep.engine.executors`, default this process) runs the
    tasks, so ``--executor dask`` spreads them over a cluster
    (:meth:`HopfScan.tasks` says how rows are grouped into tasks).
    Persistence, resuming and progress are those of every scan
    (:func:`pendsweep.engine.scan.run_scan`, keyed by ``mass_point, point,
    method``). Scans whose work estimate (:meth:`HopfScan.work`) exceeds
    ``max_work`` integration steps are refused (None: no limit); a finished
    row is written at most ``checkpoint_seconds`` s after it finishes. Returns the
    rows sorted by mass, omega_hat and method order (None with
    ``return_rows=False``, which never holds all rows; read them back from ``output``).
    """
    return run_scan(
        HopfScan(config),
        output,
        n_jobs=n_jobs,
        progress=progress,
        overwrite=overwrite,
        executor=executor,
        max_work=max_work,
        checkpoint_seconds=checkpoint_seconds,
        return_rows=return_rows,
    )


def _ordered(df: pd.DataFrame, config: HopfConfig) -> pd.DataFrame:
    # Categorical codes, not Series.map over a dict: a million rows in milliseconds.
    rank = pd.Categorical(df["method"], categories=list(config.methods)).codes
    df = df.assign(_m=rank).sort_values(["mass_point", "point", "_m"], kind="stable")
    return df.drop(columns="_m").reset_index(drop=True)
