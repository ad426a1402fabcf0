"""The emulated (complete, purely numerical) system, Eq. (11)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from ..errors import ConfigError
from ..kernels import N_RECORD_COLUMNS, emulated_periods, emulated_trace
from ..model.params import ModelParams
from ._base import BackendBase, PointRun, register
from ._batch import batched_evidence, run_batch
from .gpu import GPU_BATCH_POINTS, check_device
from .status import Status

if TYPE_CHECKING:  # pandas (0.3 s) is imported by the functions that build frames, not by importing this module
    import pandas as pd


@register
@dataclass(frozen=True)
class EmulatedBackend(BackendBase):
    """Fixed-step RK4 of the complete system, with a batched kernel for many points.

    Attributes
    ----------
    dt : float
        Requested step [s] (default 1 ms, as in the paper). The step actually
        used is ``1 / (fe * round(1 / (fe * dt)))`` so that every forcing period
        holds a whole number of steps (e.g. 455 steps of 0.9990 ms at 2.2 Hz).
    signum : {"step", "stage"}
        Evaluate sgn(thetadot) in the damping once per step and hold it over
        the RK4 stages (``"step"``, the paper's choice) or at every stage.
    device : {"cpu", "cuda"}
        Where :meth:`run_points` (fresh and multistart sweeps, Hopf simulate
        scans) integrates: the CPU batched kernel, or one CUDA GPU thread per
        point (``pip install 'pendsweep[cuda]'``; see docs/gpu.md). Single
        points (:meth:`run_point`, continue-mode branches, traces) always run
        on the CPU.
    precision : {"float64", "float32"}
        Arithmetic of ``device="cuda"``; float32 is opt-in (its error is
        measured in docs/gpu.md), the CPU kernels are float64 only.
    """

    name: ClassVar[str] = "emulated"
    batched: ClassVar[bool] = True
    dt: float = 1e-3
    signum: str = "step"
    device: str = "cpu"
    precision: str = "float64"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ConfigError(f"dt = {self.dt!r} s must be a positive finite step")
        if self.signum not in ("step", "stage"):
            raise ConfigError(f"signum = {self.signum!r}; choose 'step' or 'stage'")
        check_device(self.device, self.precision)

    def validate(self, params: ModelParams) -> None:
        if 1.0 / params.fe < self.dt:
            raise ConfigError(f"forcing period 1/fe = {1 / params.fe:g} s is shorter than dt = {self.dt:g} s")

    @property
    def min_batch_points(self) -> int:
        """Fewest points worth one :meth:`run_points` call: a GPU needs ~1e5 threads to be busy."""
        return GPU_BATCH_POINTS if self.device == "cuda" else 1

    def initial_state(self, params, y, ydot, theta, thetadot) -> np.ndarray:
        return np.array([y, ydot, theta, thetadot], dtype=np.float64)

    def run_point(self, params, state, transient_periods, record_periods) -> PointRun:
        state = np.ascontiguousarray(state, dtype=np.float64).copy()
        records = np.empty((record_periods, N_RECORD_COLUMNS), dtype=np.float64)
        records.fill(np.nan)
        code, done = emulated_periods(
            state,
            params.kernel_array(),
            params.alpha,
            params.fe,
            self.steps_per_period(params),
            transient_periods,
            self.signum == "stage",
            records,
        )
        return PointRun(records, state, Status.from_code(code), int(done))

    def run_points(self, params, states, transient_periods, record_periods, threads=None) -> list[PointRun]:
        """Many independent points at once with the batched, vectorised kernel.

        ``params`` is a sequence of n :class:`ModelParams`, ``states`` an
        ``(n, 4)`` array; returns one :class:`PointRun` per point, as
        :meth:`run_point` would (to about 1e-12 relative on periodic motion).
        ``threads`` limits the numba threads (default: all).
        """
        batch = run_batch(
            params,
            states,
            transient_periods,
            record_periods,
            dt=self.dt,
            signum=self.signum,
            threads=threads,
            device=self.device,
            precision=self.precision,
        )
        return [
            PointRun(batch.records[i], batch.states[i], Status.from_code(batch.status[i]), int(batch.periods_done[i]))
            for i in range(len(params))
        ]

    def evidence_many(self, params, finals, firsts, scales, **schedule) -> list[tuple[np.ndarray, np.ndarray]]:
        """The motion classifier's evidence for many points in one batched launch.

        See :func:`pendsweep.backends._batch.batched_evidence`; ``schedule`` holds its
        keyword arguments (periods, twin separation, rest threshold).
        """
        return batched_evidence(params, finals, firsts, scales, dt=self.dt, signum=self.signum, **schedule)

    def trace(self, params, state, periods, stride=1) -> pd.DataFrame:
        n = self.steps_per_period(params)
        state = np.ascontiguousarray(state, dtype=np.float64).copy()
        out = np.full((periods * n // stride + 1, 5), np.nan)
        emulated_trace(
            state, params.kernel_array(), params.alpha, params.fe, n, periods, self.signum == "stage", stride, out
        )
        import pandas as pd

        df = pd.DataFrame(out, columns=["t", "y", "ydot", "theta", "thetadot"])
        df["Fe"] = params.alpha * np.sin(2 * np.pi * params.fe * df["t"].to_numpy())
        return df
