"""Shooting on the stroboscopic map of the emulated system, Eq. (11).

``P^k`` maps the state ``(y, ydot, theta, thetadot)`` at forcing phase 0 to
the state ``k`` forcing periods later. A ``k``-periodic orbit is a zero of
``G(x) = P^k(x) - x`` (theta wrapped, so rotating orbits count); no phase
condition is needed because the forcing fixes the phase. The Jacobian
``dP^k/dx`` comes from the variational equations integrated with the same
fixed-step RK4 (:func:`pendsweep.kernels._variational.variational_periods`),
``dt = 1 / (fe n)`` with ``n`` the steps per period chosen as the backends
choose them (:func:`pendsweep.backends.steps_per_period`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...backends import steps_per_period
from ...kernels import N_RECORD_COLUMNS, STATUS_OK, wrap_angle
from ...kernels._layout import REC_THETA_SEC, REC_THETADOT_SEC, REC_Y_SEC, REC_YDOT_SEC
from ...kernels._variational import variational_periods
from ...model.params import ModelParams
from ..semi_trivial import semi_trivial_response
from .problem import Evaluation, EvaluationFailed

#: Record columns of the section (y, ydot, theta, thetadot).
SECTION = [REC_Y_SEC, REC_YDOT_SEC, REC_THETA_SEC, REC_THETADOT_SEC]


class OrbitDiverged(EvaluationFailed):
    """The orbit became non-finite during a shooting evaluation (treated as a failed step)."""


@dataclass
class OrbitInfo:
    """Per-period records ``(k, N_RECORD_COLUMNS)`` of the orbit and the integral of the Jacobian's trace [-]."""

    records: np.ndarray
    trace_integral: float


class PendulumShooting:
    """The ``k``-period stroboscopic map of Eq. (11) as a :class:`~pendsweep.analysis.continuation.problem.MapProblem`.

    Parameters
    ----------
    params : ModelParams
        The model; ``parameter`` is replaced by the continuation value.
    parameter : str
        Continued parameter, any :class:`~pendsweep.model.params.ModelParams` field.
    period : int
        ``k``, forcing periods per map application.
    dt : float
        Requested step [s]; ``n = round(1 / (fe dt))`` steps per period are
        fixed at ``params.fe`` for the whole continuation (so that the map is
        continuous in ``fe`` too; when ``fe`` is continued ``dt = 1/(fe n)``
        drifts with it).
    eps : float
        ``sgn(thetadot) ~ tanh(thetadot / eps)`` in the damping [rad/s];
        0 holds the sign per step as the sweep kernels do (non-smooth with b1 > 0).
    lam_scale : float
        Characteristic size of the parameter [its unit].
    """

    def __init__(
        self,
        params: ModelParams,
        parameter: str,
        period: int = 1,
        dt: float = 1e-3,
        eps: float = 1e-3,
        lam_scale: float = 1.0,
        steps: int | None = None,
    ):
        self.params = params
        self.parameter = parameter
        self.period = int(period)
        self.dt = dt
        self.eps = float(eps)
        self.lam_scale = float(lam_scale)
        self.steps = int(steps) if steps is not None else steps_per_period(params.fe, dt)
        # Lengths in units of the pendulum length, times in units of 1 / omega_e.
        w = params.omega_e
        self.scale = np.array([params.l, params.l * w, 1.0, w])

    def with_period(self, period: int) -> PendulumShooting:
        return PendulumShooting(self.params, self.parameter, period, self.dt, self.eps, self.lam_scale, self.steps)

    def at(self, parameter: str, value: float) -> PendulumShooting:
        """The same problem with another model ``parameter`` fixed at ``value`` (steps per period kept)."""
        return PendulumShooting(
            self.params.replace(**{parameter: value}), self.parameter, self.period, self.dt, self.eps,
            self.lam_scale, self.steps,
        )  # fmt: skip

    def section(self, x: np.ndarray) -> np.ndarray:
        """The section ``(y, ydot, theta, thetadot)`` of the state ``x`` (the state itself)."""
        return np.asarray(x)

    def params_at(self, lam: float) -> ModelParams:
        """The model at parameter value ``lam`` (ParameterError outside its range)."""
        return self.params.replace(**{self.parameter: lam})

    def evaluate(self, x: np.ndarray, lam: float, tangent: bool = True) -> Evaluation:
        """``P^k(x) - x`` (theta difference wrapped), ``dP^k/dx`` and the orbit's records.

        The monodromy matrix is always integrated (one kernel for both uses);
        ``tangent`` only decides whether it is returned.
        """
        q = self.params_at(lam)
        state = np.array(x, dtype=np.float64)
        phi = np.eye(4)
        records = np.empty((self.period, N_RECORD_COLUMNS))
        status, trace = variational_periods(
            state, phi, q.kernel_array(), q.alpha, q.fe, self.steps, self.period, self.eps, records
        )
        if status != STATUS_OK:
            raise OrbitDiverged(f"orbit diverged at {self.parameter} = {lam:g}")
        residual = state - x
        residual[2] = wrap_angle(residual[2])
        return Evaluation(residual, phi if tangent else None, OrbitInfo(records, trace))

    def subperiod_distance(self, x: np.ndarray, info: OrbitInfo) -> float:
        """Scaled max-norm distance between ``x`` and the section after ``k/2`` periods (inf for odd ``k``)."""
        if self.period % 2:
            return math.inf
        d = info.records[self.period // 2 - 1, SECTION] - x
        d[2] = wrap_angle(d[2])
        return float(np.abs(d / self.scale).max())

    def image_distance(self, info: OrbitInfo, y: np.ndarray) -> float:
        """Scaled 2-norm distance from ``y`` to the nearest section after 1 ... k-1 periods (inf for ``k = 1``)."""
        d = info.records[: self.period - 1][:, SECTION] - y
        if not d.size:
            return math.inf
        d[:, 2] = (d[:, 2] + math.pi) % (2.0 * math.pi) - math.pi
        return float(np.sqrt(((d / self.scale) ** 2).sum(axis=1)).min())


def semi_trivial_section(params: ModelParams) -> np.ndarray:
    """``(y, ydot, 0, 0)`` at forcing phase 0 of the oscillator's steady response, pendulum at rest.

    Exact for the linear spring (up to the RK4 error, which Newton removes);
    with ``k3 != 0`` the linear response is only the Newton start.
    """
    Y = semi_trivial_response(params.replace(k3=0.0))
    # y = Im(Y exp(i w t)): at t = 0, y = Im Y and ydot = w Re Y.
    return np.array([Y.imag, params.omega_e * Y.real, 0.0, 0.0])
