"""Two-parameter maps: the settled motion class and swing over a grid of two model parameters.

Every grid cell is one run from the same initial condition (default
theta = 0.1 rad, the paper's fresh start), integrated on the batched
emulated kernel in rounds until it settles (:func:`pendsweep.studies.basins.settle_runs`)
or reaches ``max_periods``. A cell records its motion class
(``semi-trivial``, ``periodic-n``, ``rotating``, ``unsettled`` or ``n/a``),
the settled max |theta| and the settling time. When one axis is ``alpha``
the Hopf boundary of the semi-trivial solution is computed along the other
axis with Eq. (12) and Floquet theory (:mod:`pendsweep.studies.hopf`) and drawn over
the map.
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..backends import EmulatedBackend
from ..backends.gpu import check_device
from ..backends.status import Status
from ..errors import ConfigError
from ..model.params import PARAM_SPECS, ModelParams, check_value
from .basins import CHUNK_STARTS, ROUND_PERIODS, EmulatedMap, settle_runs
from .basins.run import SettleScan, chunk_ranges

ROW_COLUMNS = ["ix", "iy"]
#: Values of the non-alpha axis at which the Hopf boundary is computed (at most).
BOUNDARY_POINTS = 60


def parse_axis(text: str, name: str) -> tuple[float, ...]:
    """``A:B:N`` (N values from A to B inclusive) or a single number, for parameter ``name``."""
    parts = str(text).split(":")
    try:
        if len(parts) == 1:
            return (float(parts[0]),)
        if len(parts) == 3:
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
            if n < 1 or not (math.isfinite(a) and math.isfinite(b)):
                raise ValueError
            return tuple(np.linspace(a, b, n))
    except ValueError:
        pass
    raise ConfigError(f"--{name} {text!r}: give FROM:TO:N (N >= 1 values, finite ends) or one number")


@dataclass(frozen=True)
class MapConfig:
    """Everything that determines a two-parameter map (stored in the result file).

    Attributes
    ----------
    x, y : str
        Parameter names of the horizontal and vertical axes.
    x_values, y_values : tuple of float
        Grid values (SI units of the parameters).
    model : dict
        Overrides of the default :class:`~pendsweep.model.params.ModelParams`.
    initial : (theta0 [rad], thetadot0 [rad/s])
        Start of every cell, with y = ydot = 0.
    max_periods, round_periods : int
        Cap on forcing periods per cell; periods between settling checks.
    dt : float
        Requested RK4 step [s]; signum : "step" or "stage".
    device, precision : str
        Where the cells integrate: ``"cpu"`` or ``"cuda"`` (GPU precision
        ``"float64"`` or ``"float32"``).
    """

    x: str
    x_values: tuple[float, ...]
    y: str
    y_values: tuple[float, ...]
    model: dict[str, float] = field(default_factory=dict)
    initial: tuple[float, float] = (0.1, 0.0)
    max_periods: int = 300
    round_periods: int = ROUND_PERIODS
    dt: float = 1e-3
    signum: str = "step"
    device: str = "cpu"
    precision: str = "float64"

    def __post_init__(self) -> None:
        from ..analysis.attractors import SETTLE_WINDOW

        for axis in (self.x, self.y):
            if axis not in PARAM_SPECS:
                raise ConfigError(f"unknown parameter {axis!r}; known: {', '.join(PARAM_SPECS)}")
        if self.x == self.y:
            raise ConfigError(f"the two map axes must differ (both are {self.x!r})")
        for name, values in ((self.x, self.x_values), (self.y, self.y_values)):
            if not values:
                raise ConfigError(f"axis {name!r} has no values")
            for v in values:
                check_value(name, float(v))
        object.__setattr__(self, "x_values", tuple(float(v) for v in self.x_values))
        object.__setattr__(self, "y_values", tuple(float(v) for v in self.y_values))
        object.__setattr__(self, "initial", tuple(float(v) for v in self.initial))
        check_device(self.device, self.precision)
        for name, v, lo in (
            ("--max-periods", self.max_periods, SETTLE_WINDOW),
            ("round_periods", self.round_periods, 1),
        ):
            if int(v) != v or v < lo:
                raise ConfigError(f"{name} = {v!r} must be an integer >= {lo}")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ConfigError(f"dt = {self.dt!r} s must be a positive finite step")
        for xv in (self.x_values[0], self.x_values[-1]):
            for yv in (self.y_values[0], self.y_values[-1]):
                p = self.params_at(xv, yv)
                if 1.0 / p.fe < self.dt:
                    raise ConfigError(f"forcing period 1/fe = {1 / p.fe:g} s is shorter than dt = {self.dt:g} s")

    @property
    def base_params(self) -> ModelParams:
        return ModelParams.from_mapping(self.model)

    def params_at(self, xv: float, yv: float) -> ModelParams:
        return self.base_params.replace(**{self.x: xv, self.y: yv})

    @property
    def cells(self) -> int:
        return len(self.x_values) * len(self.y_values)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d.update(x_values=list(self.x_values), y_values=list(self.y_values), initial=list(self.initial))
        d["model"] = self.base_params.to_dict()
        return d


def _map_task(config: MapConfig, cells: np.ndarray) -> list:
    from ..engine.scan import UnitResult

    ny = len(config.y_values)
    ix, iy = cells // ny, cells % ny
    params = tuple(config.params_at(config.x_values[i], config.y_values[j]) for i, j in zip(ix, iy))
    states = np.zeros((cells.size, 4))
    states[:, 2:] = config.initial
    runs = settle_runs(
        EmulatedMap(params, config.dt, config.signum, device=config.device, precision=config.precision),
        states,
        config.max_periods,
        round_periods=config.round_periods,
    )
    df = pd.DataFrame(
        {
            config.x: np.asarray(config.x_values)[ix],
            config.y: np.asarray(config.y_values)[iy],
            "ix": ix.astype(np.int64),
            "iy": iy.astype(np.int64),
            "status": [Status.from_code(c).value for c in runs.status],
            "motion": runs.motion.astype(str),
            "period": runs.period,
            "rotation_number": runs.turns / np.maximum(runs.period, 1),
            "settle_periods": runs.settle_periods,
            "periods_done": runs.periods_done,
            "theta_absmax": runs.theta_absmax,
        }
    )
    return [UnitResult(f"cells:{int(cells[0])}", df)]


@dataclass
class MapScan(SettleScan):
    """A two-parameter map as a scan: one unit per chunk of grid cells."""

    config: MapConfig
    chunk_cells: int = CHUNK_STARTS
    desc: str = "map"
    row_columns: list[str] = field(default_factory=lambda: list(ROW_COLUMNS))

    def metadata(self) -> dict[str, Any]:
        from ..engine.results import run_metadata

        return run_metadata("map", self.config.to_dict(), backend="emulated")

    def chunks(self) -> list[tuple[str, np.ndarray]]:
        # A GPU needs ~1e5 threads to be busy: its units hold at least the backend's minimum batch.
        size = max(self.chunk_cells, EmulatedBackend(device=self.config.device).min_batch_points)
        return [(f"cells:{int(cells[0])}", cells) for cells in chunk_ranges(self.config.cells, size)]

    def unit_task(self, payload: np.ndarray, n_jobs: int):
        return functools.partial(_map_task, self.config, payload)

    def starts(self) -> int:
        return self.config.cells

    def steps_per_period(self) -> float:
        from ..backends import steps_per_period

        corners = [(x, y) for x in (self.config.x_values[0], self.config.x_values[-1])
                   for y in (self.config.y_values[0], self.config.y_values[-1])]  # fmt: skip
        return float(np.mean([steps_per_period(self.config.params_at(x, y).fe, self.config.dt) for x, y in corners]))


def run_map(
    config: MapConfig,
    output: Path | None = None,
    *,
    progress: bool = False,
    overwrite: bool = False,
    executor=None,
    chunk_cells: int = CHUNK_STARTS,
    max_work: float | None = None,
    checkpoint_seconds: float = 1.0,
    return_rows: bool = True,
) -> pd.DataFrame | None:
    """Run (or resume) a two-parameter map; one row per grid cell.

    Cells go in units of ``chunk_cells`` (at least
    :data:`pendsweep.backends.gpu.GPU_BATCH_POINTS` on a GPU), each on the batched kernel with
    all cores, run by the scan engine (:func:`pendsweep.engine.scan.run_scan`):
    finished units are persisted (at most ``checkpoint_seconds`` s after
    they finish) and skipped on a rerun. ``max_work``
    limits the work estimate (every cell to the cap); None: no limit.
    ``return_rows=False`` (with ``output``): return None and never hold all
    rows (read the columns needed back from ``output``).
    """
    from ..engine.scan import run_scan

    return run_scan(
        MapScan(config, chunk_cells),
        output,
        progress=progress,
        overwrite=overwrite,
        executor=executor,
        max_work=max_work,
        checkpoint_seconds=checkpoint_seconds,
        return_rows=return_rows,
    )


def hopf_boundaries(config: MapConfig) -> pd.DataFrame | None:
    """Eq. (12) and Floquet alpha_H [N] along the non-alpha axis (None when alpha is not an axis).

    Columns: the other axis's parameter, ``analytic``, ``floquet`` (NaN where
    Floquet finds no boundary below 500 N).
    """
    from .hopf import alpha_hopf_analytic, hopf_floquet

    if "alpha" not in (config.x, config.y):
        return None
    other, values = (config.y, config.y_values) if config.x == "alpha" else (config.x, config.x_values)
    values = np.linspace(values[0], values[-1], min(BOUNDARY_POINTS, max(2, len(values))))
    rows = []
    for v in values:
        p = config.base_params.replace(**{other: float(v)})
        rows.append({other: float(v), "analytic": alpha_hopf_analytic(p), "floquet": hopf_floquet(p)["alpha_H"]})
    return pd.DataFrame(rows)
