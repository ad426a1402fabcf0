"""The backend contract and registry.

A backend turns model parameters and a state into per-period records. Every
backend must:

1. Have a unique ``name`` and be registered with :func:`register`, which makes
   it a choice of the CLI's ``--backend``.
2. Be a frozen dataclass whose fields are its options (with defaults and
   units in their docstrings); :meth:`validate` raises ``ConfigError`` for bad
   values. ``make_backend(name, **options)`` builds one and rejects unknown
   option names.
3. Use a state vector (contiguous float64) whose first four entries are the
   emulated-equivalent coordinates ``(y, ydot, theta, thetadot)``; later
   entries are the backend's own (actuator, filter, predictor history ...).
   The sweep planner perturbs the pendulum through ``state[2]``.
4. Implement :meth:`run_point`, returning a :class:`PointRun` whose records
   follow :data:`pendsweep.kernels.RECORD_COLUMNS`, and :meth:`trace`, a
   time-series :class:`pandas.DataFrame` with at least ``t, y, ydot, theta,
   thetadot``.
5. Never raise on a diverging point: report it through ``PointRun.status``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
import pandas as pd

from ..errors import ConfigError
from ..params import ModelParams
from ..status import Status


@dataclass
class PointRun:
    """Outcome of one point: records ``(record_periods, 8)``, final state, status."""

    records: np.ndarray
    state: np.ndarray
    status: Status
    periods_done: int


@runtime_checkable
class Backend(Protocol):
    name: ClassVar[str]

    def validate(self, params: ModelParams) -> None: ...

    def initial_state(
        self, params: ModelParams, y: float, ydot: float, theta: float, thetadot: float
    ) -> np.ndarray: ...

    def run_point(
        self,
        params: ModelParams,
        state: np.ndarray,
        transient_periods: int,
        record_periods: int,
    ) -> PointRun: ...

    def trace(
        self, params: ModelParams, state: np.ndarray, periods: int, stride: int = 1
    ) -> pd.DataFrame: ...

    def options(self) -> dict[str, Any]: ...


BACKENDS: dict[str, type] = {}


def register(cls: type) -> type:
    """Class decorator adding a backend to the registry under ``cls.name``."""
    BACKENDS[cls.name] = cls
    return cls


def make_backend(name: str, **options: Any) -> Backend:
    """Instantiate backend ``name`` with ``options`` (unknown names are errors)."""
    if name not in BACKENDS:
        raise ConfigError(f"unknown backend {name!r}; choose one of {', '.join(sorted(BACKENDS))}")
    cls = BACKENDS[name]
    known = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise ConfigError(
            f"unknown option(s) {', '.join(unknown)} for backend {name!r}; "
            f"known: {', '.join(known) or 'none'}"
        )
    converted = {}
    for key, value in options.items():
        default = known[key].default
        try:
            if isinstance(default, bool):
                converted[key] = _to_bool(value)
            elif default is None:  # an optional number: None (or "none") keeps the documented default meaning
                converted[key] = None if value is None or str(value).strip().lower() == "none" else float(value)
            else:
                converted[key] = type(default)(value)
        except (TypeError, ValueError):
            raise ConfigError(f"backend option {key}={value!r} is not a valid {type(default).__name__}") from None
    return cls(**converted)


def _to_bool(value: Any) -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in {"1", "true", "yes", "on"}:
        return True
    if text in {"0", "false", "no", "off"}:
        return False
    raise ValueError(value)


def steps_per_period(fe: float, dt: float) -> int:
    """Integer steps per forcing period closest to the requested ``dt``."""
    return max(1, int(round(1.0 / (fe * dt))))
