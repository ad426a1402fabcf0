"""Linear algebra of the continuation in scaled variables: Newton, the null tangent, the bifurcation test functions."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...errors import PendsweepError
from .problem import FOLD, NEIMARK_SACKER, PERIOD_DOUBLING, MapProblem, Settings


# -- linear algebra in scaled variables ------------------------------------------
@dataclass
class _Scaled:
    """A problem seen in the scaled variables ``X = x / scale``, ``L = lam / lam_scale``."""

    problem: MapProblem
    settings: Settings

    @property
    def n(self) -> int:
        return self.problem.scale.size

    def unpack(self, u: np.ndarray) -> tuple[np.ndarray, float]:
        return u[:-1] * self.problem.scale, float(u[-1] * self.problem.lam_scale)

    def pack(self, x: np.ndarray, lam: float) -> np.ndarray:
        return np.append(x / self.problem.scale, lam / self.problem.lam_scale)

    def residual_and_jacobian(self, u: np.ndarray, with_lam: bool = True):
        """Scaled residual ``(n,)``, ``[G_X G_L]`` ``(n, n+1)`` and the evaluation at ``u``."""
        p, s = self.problem, self.problem.scale
        x, lam = self.unpack(u)
        ev = p.evaluate(x, lam, tangent=True)
        r = ev.residual / s
        jx = (ev.jacobian - np.eye(self.n)) * s[None, :] / s[:, None]
        jl = np.zeros(self.n)
        if with_lam:
            h = self.settings.lam_step * max(abs(lam), p.lam_scale)
            try:
                minus, width = p.evaluate(x, lam - h, tangent=False).residual, 2.0 * h
            except PendsweepError:  # lam - h is outside the parameter's range: one-sided difference
                minus, width = ev.residual, h
            plus = p.evaluate(x, lam + h, tangent=False).residual
            jl = (plus - minus) / width * p.lam_scale / s
        return r, np.column_stack([jx, jl]), ev


def newton(fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], x0: np.ndarray, tol: float, max_iterations: int):
    """Newton's method on ``fun(x) = (residual, jacobian)`` (square).

    Converged when the max-norm of the last update is below ``tol`` and the
    residual it corrected was below ``max(tol, 10 * update)`` (the quadratic
    regime, where the residual and the update are of one size). Returns
    ``(x, converged, updates)`` with the max-norm of every update taken (for
    convergence-order checks).
    """
    x = np.array(x0, dtype=float)
    updates: list[float] = []
    for _ in range(max_iterations):
        r, jac = fun(x)
        if not np.all(np.isfinite(r)) or not np.all(np.isfinite(jac)):
            return x, False, updates
        try:
            dx = np.linalg.solve(jac, -r)
        except np.linalg.LinAlgError:
            return x, False, updates
        x = x + dx
        step = float(np.abs(dx).max())
        updates.append(step)
        if step < tol and float(np.abs(r).max()) < max(tol, 10 * step):
            return x, True, updates
        if not math.isfinite(step) or step > 1e3:
            return x, False, updates
    return x, False, updates


def null_tangent(a: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """Unit null vector of the ``(n, n+1)`` matrix ``a``, oriented along ``previous``."""
    bordered = np.vstack([a, previous])
    rhs = np.zeros(a.shape[0] + 1)
    rhs[-1] = 1.0
    try:
        t = np.linalg.solve(bordered, rhs)
    except np.linalg.LinAlgError:
        t = np.linalg.svd(a)[2][-1]
    t /= np.linalg.norm(t)
    return t if t @ previous >= 0 else -t


def test_functions(multipliers: np.ndarray) -> dict[str, float]:
    """Fold, period-doubling and Neimark-Sacker test functions of the multipliers (module table)."""
    mu = multipliers
    pairs = [mu[i] * mu[j] - 1.0 for i in range(mu.size) for j in range(i + 1, mu.size)]
    return {
        FOLD: float(np.prod(mu - 1.0).real),
        PERIOD_DOUBLING: float(np.prod(mu + 1.0).real),
        NEIMARK_SACKER: float(np.prod(pairs).real) if pairs else 1.0,
    }


def falsi_point(lo: float, hi: float, f_lo: float, f_hi: float) -> float:
    """The regula falsi trial inside the bracket ``(lo, hi)`` (its midpoint when the secant leaves it)."""
    s = hi - f_hi * (hi - lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (lo + hi)
    return s if lo < s < hi else 0.5 * (lo + hi)


def illinois_update(lo: float, hi: float, f_lo: float, f_hi: float, s: float, f: float, side: int):
    """The bracket after a trial ``(s, f)``; the end kept twice in a row has its value halved (Illinois).

    Returns ``(lo, hi, f_lo, f_hi, side)``, ``side`` -1 when ``lo`` moved last, +1 when ``hi`` did.
    """
    if np.sign(f) == np.sign(f_lo):
        if side == -1:
            f_hi *= 0.5
        return s, hi, f, f_hi, -1
    if side == 1:
        f_lo *= 0.5
    return lo, s, f_lo, f, 1
