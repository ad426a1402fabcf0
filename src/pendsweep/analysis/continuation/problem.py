"""What a continuation works on and produces: the map problem, settings, points, branches, bifurcation labels, errors."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from ...errors import PendsweepError

FOLD = "fold"
PERIOD_DOUBLING = "period-doubling"
NEIMARK_SACKER = "neimark-sacker"
#: A multiplier +1 without a fold (e.g. a symmetry-breaking pitchfork); reported, not followed.
BRANCH_POINT = "branch-point"
#: Why a doubled branch ends: it has shrunk onto the orbit of half its period.
REACHED = "reached its period doubling"
#: Why a branch ends: it has come back to its start (an isola, or a loop through folds).
CLOSED = "closed loop"


class MapProblem(Protocol):
    """A map ``P(x; lam)`` whose fixed points are continued.

    Attributes
    ----------
    scale : float64[n]
        Characteristic size of each state component (its unit); Newton
        tolerances and arclength are measured in ``x / scale``.
    lam_scale : float
        Characteristic size of the parameter [parameter unit].
    period : int
        How many applications of the underlying one-period map ``P`` is (``k``).
    """

    scale: np.ndarray
    lam_scale: float
    period: int

    def evaluate(self, x: np.ndarray, lam: float, tangent: bool = True) -> Evaluation:
        """``G(x, lam) = P(x; lam) - x`` and ``dP/dx`` (when ``tangent``).

        May raise :class:`EvaluationFailed` or a ParameterError (``lam`` out of range).
        """

    def with_period(self, period: int) -> MapProblem:
        """The same system over ``period`` applications of the one-period map."""

    def subperiod_distance(self, x: np.ndarray, info: Any) -> float:
        """Scaled distance (``info`` from :meth:`evaluate`) of the orbit through ``x`` from an orbit of half its period (inf if none)."""

    def image_distance(self, info: Any, y: np.ndarray) -> float:
        """Scaled distance from ``y`` to the nearest other section point of the orbit evaluated in ``info`` (inf if ``k = 1``)."""


@dataclass
class Evaluation:
    """One evaluation of a map problem.

    Attributes
    ----------
    residual : float64[n]
        ``P(x) - x`` (angles may be wrapped), in state units.
    jacobian : float64[n, n] or None
        ``dP/dx`` (the monodromy matrix for a stroboscopic map).
    info : Any
        Problem-specific extras (e.g. per-period records of the orbit).
    """

    residual: np.ndarray
    jacobian: np.ndarray | None
    info: Any = None


@dataclass
class Settings:
    """Continuation controls (scaled units: state / scale, parameter / lam_scale).

    Attributes
    ----------
    ds, ds_min, ds_max : float
        First, smallest and largest arclength step.
    newton_tol : float
        Newton stops when the scaled max-norm of the update is below this
        (and the residual it corrected is of the same size, :func:`newton`).
    max_iterations : int
        Corrector iterations before a step counts as failed.
    fast_iterations : int
        A corrector this fast lets the step grow.
    max_turn : float
        Largest angle [rad] between consecutive tangents; larger turns are
        retried with half the step (keeps the march on its branch).
    max_correction : float
        Largest corrector displacement as a fraction of the step; longer
        corrections are retried with half the step (they land on another branch).
    max_points : int
        Points per direction and branch.
    locate_tol : float
        Arclength tolerance of bifurcation location.
    lam_step : float
        Relative finite-difference step of the parameter derivative.
    max_period : int
        Largest period (in applications of the one-period map) that branch
        switching at period doublings produces.
    switch_offset : float
        Scaled distance from the period-doubling point along the critical
        eigenvector where the doubled branch is entered.
    """

    ds: float = 0.02
    ds_min: float = 1e-6
    ds_max: float = 0.05
    newton_tol: float = 1e-10
    max_iterations: int = 10
    fast_iterations: int = 3
    max_turn: float = 0.5
    max_correction: float = 0.3
    max_points: int = 400
    locate_tol: float = 1e-9
    lam_step: float = 1e-6
    max_period: int = 4
    switch_offset: float = 0.02


@dataclass
class Point:
    """An accepted point of a branch (state units)."""

    x: np.ndarray
    lam: float
    multipliers: np.ndarray
    tangent: np.ndarray  # scaled (X, L), unit
    info: Any = None

    @property
    def max_multiplier(self) -> float:
        return float(np.abs(self.multipliers).max())

    @property
    def stable(self) -> bool:
        return self.max_multiplier < 1.0


@dataclass
class Bifurcation:
    """A located bifurcation on branch ``branch``."""

    kind: str
    lam: float
    branch: int
    x: np.ndarray
    multipliers: np.ndarray
    critical_vector: np.ndarray | None = None  # state units; eigenvector of the critical multiplier


@dataclass
class Branch:
    """Points of one branch in arclength order, and why each end stopped."""

    period: int
    points: list[Point] = field(default_factory=list)
    ends: list[str] = field(default_factory=list)
    origin: str = "start"


@dataclass
class Result:
    """Branches (the first through the start), the located bifurcations, and the converged start point."""

    branches: list[Branch]
    bifurcations: list[Bifurcation]
    start: Point | None = None


class ContinuationError(RuntimeError):
    """A continuation cannot start (no convergence at the starting point): a runtime failure, exit 1."""


class EvaluationFailed(Exception):
    """A problem could not evaluate its map (e.g. a diverged orbit); the step is retried smaller."""


#: A located Neimark-Sacker point has a complex multiplier with | |mu| - 1 | below this (the
#: location is to ``locate_tol`` in arclength, so a true crossing is far closer).
NS_MODULUS_TOL = 1e-3

#: Imaginary part [-] above which a multiplier counts as complex (eigvals of a real matrix return
#: real pairs with round-off imaginary parts of about 1e-16 relative).
COMPLEX_IMAG = 1e-8

#: Corrector iterations allowed while locating a bifurcation: next to a branch point the bordered
#: Jacobian is singular and Newton converges only linearly (about halving the error per iteration).
LOCATE_ITERATIONS = 50

#: Trial points of a bifurcation location that may fail to correct before it gives up (each retry
#: halves the distance to a bracket end, so the bracket shrinks; see :meth:`Continuation.locate`).
LOCATE_RETRIES = 12

#: What a failed trial step may raise: the parameter left its range, or the map failed.
_STEP_FAILURES = (PendsweepError, EvaluationFailed)
