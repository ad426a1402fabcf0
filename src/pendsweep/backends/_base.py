"""The backend contract and registry.

A backend turns model parameters and a state into per-period records. Every
backend must:

1. Have a unique ``name`` and be registered with :func:`register`, which makes
   it a choice of the CLI's ``--backend``.
2. Be a frozen dataclass whose fields are its options (with defaults and
   units in their docstrings); :meth:`validate` raises ``ConfigError`` for bad
   values. ``make_backend(name, **options)`` builds one and rejects unknown
   option names.
3. Own its state vector (contiguous float64). Callers never index it: they
   build one with :meth:`initial_state`, perturb the pendulum with
   :meth:`kick` (which returns a new state) and read the Poincare
   coordinates ``(y, ydot, theta, thetadot)`` with :meth:`section`.
4. Say how many integration steps one forcing period takes
   (:meth:`steps_per_period`; scans estimate their work from it).
5. Implement :meth:`run_point`, returning a :class:`PointRun` whose records
   follow :data:`pendsweep.kernels.RECORD_COLUMNS`, and :meth:`trace`, a
   time-series :class:`pandas.DataFrame` with at least ``t, y, ydot, theta,
   thetadot``.
6. Implement :meth:`run_points` for many independent points. ``batched``
   declares whether it is a vectorised kernel (``True``: scans hand it
   chunks of many points and give each chunk all cores) or the documented
   fallback of :class:`BackendBase`, one :meth:`run_point` after another
   (``False``: scans run one point per task, several tasks in parallel).
   A batched backend also provides ``evidence_many(params, finals, firsts,
   scales, **schedule)``, the motion classifier's record extensions and
   Lyapunov twins in one launch (see
   :meth:`pendsweep.backends.EmulatedBackend.evidence_many`); for the others
   the classifier re-simulates point by point with :meth:`run_point`.
7. Never raise on a diverging point: report it through ``PointRun.status``.
8. Say whether a run may start from any given state (``restartable``; default
   True). A backend whose specimen lives elsewhere (a remote rig) is not:
   sweeps then run fresh points one at a time, and the classifier judges
   points by their records alone.
9. Say whether its records carry measurement or process noise
   (``noisy``; default False). The classifier then measures each record's
   own noise and sets its periodicity tolerance from it
   (:func:`pendsweep.analysis.sections.measured_noise`); a noise-free record must
   repeat to :data:`pendsweep.analysis.sections.PERIODIC_TOL`.

:class:`BackendBase` supplies the defaults (a state whose first four
entries are ``(y, ydot, theta, thetadot)``, the per-point fallback of
:meth:`run_points`, steps from a ``dt`` field, options from the fields,
``restartable``, ``noisy``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from ..errors import ConfigError
from ..model.params import ModelParams
from .status import Status

if TYPE_CHECKING:  # pandas (0.3 s) is imported by the functions that build frames, not by importing this module
    import pandas as pd


@dataclass
class PointRun:
    """Outcome of one point: records ``(record_periods, 8)``, final state, status.

    ``round_trip`` holds the 50th and 99th percentile and the largest of the
    protocol's round trips [s] when the point ran against a remote rig (None otherwise).
    """

    records: np.ndarray
    state: np.ndarray
    status: Status
    periods_done: int
    round_trip: np.ndarray | None = None


@runtime_checkable
class Backend(Protocol):
    """What sweeps, Hopf scans and the classifier may ask of a backend (module docstring)."""

    name: ClassVar[str]
    #: True when :meth:`run_points` is a vectorised kernel worth whole chunks of points
    #: (and ``evidence_many`` exists, module docstring item 6).
    batched: ClassVar[bool]

    @property
    def restartable(self) -> bool: ...

    @property
    def noisy(self) -> bool:
        """Whether records carry sensor or process noise (module docstring item 9)."""
        ...

    @property
    def min_batch_points(self) -> int:
        """Fewest points worth one :meth:`run_points` call (scans make tasks at least this big)."""
        ...

    def validate(self, params: ModelParams) -> None: ...

    def steps_per_period(self, params: ModelParams) -> int: ...

    def initial_state(
        self, params: ModelParams, y: float, ydot: float, theta: float, thetadot: float
    ) -> np.ndarray: ...

    def kick(self, state: np.ndarray, dtheta: float) -> np.ndarray: ...

    def section(self, state: np.ndarray) -> np.ndarray: ...

    def run_point(
        self,
        params: ModelParams,
        state: np.ndarray,
        transient_periods: int,
        record_periods: int,
    ) -> PointRun: ...

    def run_points(
        self,
        params: Sequence[ModelParams],
        states: np.ndarray,
        transient_periods: int,
        record_periods: int,
        threads: int | None = None,
    ) -> list[PointRun]: ...

    def trace(self, params: ModelParams, state: np.ndarray, periods: int, stride: int = 1) -> pd.DataFrame: ...

    def options(self) -> dict[str, Any]: ...


#: Index of theta in :class:`BackendBase` states (after y, ydot).
_THETA = 2


class BackendBase:
    """Defaults of the contract for backends whose state starts ``(y, ydot, theta, thetadot)``.

    A backend subclasses it (as a frozen dataclass with a ``dt`` field) and
    overrides what differs: a batched kernel overrides :meth:`run_points` and
    sets ``batched = True``.
    """

    batched: ClassVar[bool] = False

    @property
    def restartable(self) -> bool:
        """Whether a point can start from any given state (False: a physical specimen elsewhere owns the state).

        A backend that is not restartable runs fresh points one at a time, and
        the classifier cannot re-run a point for its evidence.
        """
        return True

    @property
    def noisy(self) -> bool:
        """Whether records carry sensor or process noise: False, a noise-free model (module docstring item 9)."""
        return False

    @property
    def min_batch_points(self) -> int:
        """Fewest points worth one :meth:`run_points` call: 1 unless a device needs many."""
        return 1

    def steps_per_period(self, params: ModelParams) -> int:
        """Whole steps per forcing period closest to the backend's ``dt`` [s]."""
        return steps_per_period(params.fe, self.dt)  # type: ignore[attr-defined]

    def options(self) -> dict[str, Any]:
        return dataclasses.asdict(self)  # type: ignore[call-overload]

    def kick(self, state: np.ndarray, dtheta: float) -> np.ndarray:
        """A copy of ``state`` with the pendulum angle moved by ``dtheta`` [rad]; nothing else changes."""
        kicked = np.array(state, dtype=np.float64, copy=True)
        kicked[_THETA] += dtheta
        return kicked

    def section(self, state: np.ndarray) -> np.ndarray:
        """Poincare coordinates ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])``, float64[4]."""
        return np.array(state[:4], dtype=np.float64, copy=True)

    def run_points(self, params, states, transient_periods, record_periods, threads=None) -> list[PointRun]:
        """The fallback for many points: :meth:`run_point` on each in turn (``threads`` unused).

        ``params`` is a sequence of n :class:`ModelParams`, ``states`` n states.
        """
        return [
            self.run_point(q, s, transient_periods, record_periods)  # type: ignore[attr-defined]
            for q, s in zip(params, states)
        ]


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
            f"unknown option(s) {', '.join(unknown)} for backend {name!r}; known: {', '.join(known) or 'none'}"
        )
    if hasattr(cls, "check_options"):
        cls.check_options(options)
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
