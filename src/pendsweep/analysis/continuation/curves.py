"""Curves of fold, period-doubling and Neimark-Sacker points in two parameters (issue 32).

A bifurcation of a periodic orbit found in one parameter ``lam1`` (by
:mod:`.core`) is traced in a second ``lam2``. Any map problem with an
``at(parameter, value)`` method (:class:`~.shooting.PendulumShooting`, the
hybrid loop's :class:`~.loop.LoopShooting`) works; nothing here knows the
pendulum.

Pseudo-arclength continuation of ``F(u) = 0`` as in :mod:`.core`: the
tangent is the null vector of ``dF/du``, Newton corrects on the hyperplane
normal to it, the step grows by 1.5 after a fast corrector and halves on a
failure or a turn of more than ``max_turn``. Convergence: the scaled
max-norm of the Newton update below ``newton_tol`` with the residual of
the same size (:func:`~.algebra.newton`).

The defining system, its test functions and the codimension-two points
they locate are in :mod:`.curve_system`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .algebra import falsi_point, illinois_update, newton, null_tangent
from .curve_system import CurveEnded, CurveProblem, _pair_turned_real, event_name, initial_reference
from .problem import _STEP_FAILURES, NEIMARK_SACKER, ContinuationError, Settings


def curve_settings(**changes: Any) -> Settings:
    """The continuation controls (:class:`~.problem.Settings`) with a curve's defaults: Newton to 1e-9
    in 8 iterations, 200 points a direction, events located to 1e-6 in arclength, steps down to 1e-5
    (the same march fields; ``lam_step``, ``max_period`` and ``switch_offset`` are not used here)."""
    return dataclasses.replace(CURVE_DEFAULTS, **changes)


#: :func:`curve_settings` without changes.
CURVE_DEFAULTS = Settings(ds_min=1e-5, newton_tol=1e-9, max_iterations=8, max_points=200, locate_tol=1e-6)


@dataclass
class CurvePoint:
    """An accepted point: orbit ``x``, both parameters, the critical multiplier and the test values."""

    u: np.ndarray
    x: np.ndarray
    lam1: float
    lam2: float
    tangent: np.ndarray
    multipliers: np.ndarray
    critical: complex
    vector: np.ndarray  # scaled right eigenvector of the critical multiplier (orientation carried along)
    normal_form: float
    tests: dict[str, float]
    info: Any = None
    event: str = ""
    step: float = math.nan  # the arclength step the march takes next from here (a resumed march reuses it)


@dataclass
class Curve:
    """Points in arclength order (start's far side first), the located events and why each end stopped."""

    kind: str
    points: list[CurvePoint] = field(default_factory=list)
    ends: list[str] = field(default_factory=list)


class CurveContinuation:
    """Trace a curve of ``curve_problem`` within ``bounds1`` x ``bounds2`` (both in parameter units)."""

    def __init__(
        self,
        curve_problem: CurveProblem,
        bounds1: tuple[float, float],
        bounds2: tuple[float, float],
        settings: Settings | None = None,
        names: tuple[str, str] = ("lam1", "lam2"),
        progress: Callable[[int], None] | None = None,
    ):
        self.cp = curve_problem
        self.settings = settings or curve_settings()
        # A finite-difference monodromy (the hybrid loop's) knows its multipliers only so well: Newton's
        # tolerance is kept ten times above that floor, or it stalls at it.
        floor = 10.0 * getattr(curve_problem.problem, "multiplier_precision", 0.0)
        if self.settings.newton_tol < floor:
            self.settings = dataclasses.replace(self.settings, newton_tol=floor)
        self.bounds = (tuple(sorted(bounds1)), tuple(sorted(bounds2)))
        self.direction = 1.0 if bounds2[1] >= bounds2[0] else -1.0
        self.names = names
        self.progress = progress or (lambda n: None)

    # .. points ..
    def make_point(self, u: np.ndarray, previous_tangent: np.ndarray, reference: complex, previous_vector):
        f, jac, (ev, a, i, mu, v, w) = self.cp.system(u, reference)
        if self.cp.kind != NEIMARK_SACKER:
            self.cp.set_border(a)  # the next steps border with this point's null vectors
        tangent = null_tangent(jac, previous_tangent)
        v_real = v.real if self.cp.kind != NEIMARK_SACKER else v
        if previous_vector is not None and float(np.real(np.vdot(previous_vector, v_real))) < 0:
            v_real, v, w = -v_real, -v, -w
        nf = self.cp.normal_form(u, a, mu[i], v, w)
        x, lam1, lam2 = self.cp.unpack(u)
        tests = self.cp.tests(mu, i, tangent, nf)
        return CurvePoint(u, x, lam1, lam2, tangent, mu, complex(mu[i]), v_real, nf, tests, ev.info)

    def correct(self, u_pred: np.ndarray, normal: np.ndarray, reference: complex, target: float = 0.0):
        """Newton on ``F(u) = 0, normal . (u - u_pred) = target``; ``(u, converged)``."""

        def fun(u):
            f, jac, _ = self.cp.system(u, reference)
            return np.append(f, normal @ (u - u_pred) - target), np.vstack([jac, normal])

        try:
            u, ok, updates = newton(fun, u_pred, self.settings.newton_tol, self.settings.max_iterations)
        except (*_STEP_FAILURES, CurveEnded, np.linalg.LinAlgError):
            return u_pred, False, self.settings.max_iterations
        return u, ok, len(updates)

    def _inside(self, lam1: float, lam2: float) -> bool:
        (a1, b1), (a2, b2) = self.bounds
        e1, e2 = 1e-12 * (b1 - a1), 1e-12 * (b2 - a2)
        return a1 - e1 <= lam1 <= b1 + e1 and a2 - e2 <= lam2 <= b2 + e2

    def _on_bound(self, prev: CurvePoint, u_out: np.ndarray) -> bool:
        """Whether ``prev`` lies on the bound that the step to ``u_out`` crosses."""
        for k, (lo, hi) in enumerate(self.bounds):
            lam = float(u_out[self.cp.n + k] * self.cp.lam_scales[k])
            value = (prev.lam1, prev.lam2)[k]
            tol = 1e-9 * (hi - lo)
            if (lam < lo and abs(value - lo) <= tol) or (lam > hi and abs(value - hi) <= tol):
                return True
        return False

    # .. start ..
    def start(self, x0: np.ndarray, lam1: float, lam2: float, reference: complex) -> CurvePoint:
        """Newton on the defining system at fixed ``lam2`` from ``(x0, lam1)``."""
        u0 = self.cp.pack(x0, lam1, lam2)
        normal = np.zeros(u0.size)
        normal[-1] = 1.0
        u, ok, _ = self.correct(u0, normal, reference)
        if not ok:
            raise ContinuationError(
                f"the {self.cp.kind} point did not converge at {self.names[1]} = {lam2:g}: "
                "start from a bifurcation of a continuation at that value"
            )
        first = np.zeros(u.size)
        first[-1] = self.direction
        return self.make_point(u, first, reference, None)

    def find_start(self, x0: np.ndarray, lam1: float, lam2: float, reference: complex) -> CurvePoint:
        """:meth:`start`, or, when Newton cannot reach the point from ``(x0, lam1)``, the same-kind bifurcation nearest ``lam1``.

        The fallback continues the orbit through ``x0`` in ``lam1`` at fixed
        ``lam2`` (:class:`~.core.Continuation`, no branch switching), from
        ``lam1`` itself or up to 5 % of the first parameter's scale on either
        side (a fold's orbit exists on one side only), and starts from the
        located bifurcation of this curve's kind nearest ``lam1``: the way
        to a hybrid loop's bifurcation from the emulated system's, when the
        loop has moved it further than Newton reaches.
        """
        try:
            return self.start(x0, lam1, lam2, reference)
        except ContinuationError as first_failure:
            failure = first_failure
        from .core import Continuation
        from .problem import Settings

        problem = self.cp.problem.at(self.cp.second, lam2)
        scale = self.cp.lam_scales[0]
        for offset in (0.0, 0.01, -0.01, 0.05, -0.05):
            origin = lam1 + offset * scale
            if not self.bounds[0][0] <= origin <= self.bounds[0][1]:
                continue
            try:
                result = Continuation(problem, self.bounds[0], Settings(max_period=1)).run(x0, origin)
            except ContinuationError:
                continue
            same = [b for b in result.bifurcations if b.kind == self.cp.kind]
            if same:
                nearest = min(same, key=lambda b: abs(b.lam - lam1))
                # the located point's own critical multiplier: the loop's pair may sit at another angle
                return self.start(nearest.x, nearest.lam, lam2, initial_reference(self.cp.kind, nearest.multipliers))
        raise failure

    # .. the march ..
    def march(
        self, start: CurvePoint, on_point: Callable[[CurvePoint], None] | None = None, budget: int | None = None
    ) -> tuple[list[CurvePoint], str]:
        """Points from ``start`` (excluded) along its tangent until a bound, an end, a failure or ``budget`` points.

        ``on_point`` sees every accepted point (located events included) as it comes. The first
        step is ``start.step`` when set (a resumed march), else ``settings.ds``.
        """
        st = self.settings
        ds = start.step if math.isfinite(start.step) else st.ds
        prev, points = start, []

        def keep(point: CurvePoint) -> None:
            points.append(point)
            if on_point is not None:
                on_point(point)

        budget = st.max_points if budget is None else budget
        while len(points) < budget:
            u_pred = prev.u + ds * prev.tangent
            if not self._inside(*self.cp.unpack(u_pred)[1:]) and self._on_bound(prev, u_pred):
                return points, "range"  # on a bound already, heading out (a delay of 0, say)
            u, ok, iterations = self.correct(u_pred, prev.tangent, prev.critical)
            ok = ok and float(np.linalg.norm(u - u_pred)) <= st.max_correction * ds
            new = None
            if ok:
                _, lam1, lam2 = self.cp.unpack(u)
                if not self._inside(lam1, lam2):
                    end = self._edge(prev, u)
                    if end is not None:
                        for point in [*self._events(prev, end, ds), end]:
                            keep(point)
                        self.progress(1)
                    return points, "range"
                try:
                    new = self.make_point(u, u - prev.u, prev.critical, prev.vector)
                except (*_STEP_FAILURES, CurveEnded):
                    ok = False
            if ok and math.acos(min(1.0, float(new.tangent @ prev.tangent))) > st.max_turn and ds > st.ds_min:
                ok = False
            if not ok:
                ds *= 0.5
                if ds < st.ds_min:
                    return points, self._why_stopped(prev)
                continue
            located = self._events(prev, new, ds)
            if iterations <= st.fast_iterations:
                ds = min(st.ds_max, 1.5 * ds)
            for point in [*located, new]:
                point.step = ds
                keep(point)
            self.progress(1)
            prev = new
        return points, "max-points"

    def _why_stopped(self, prev: CurvePoint) -> str:
        """The reason a march could not step on: the critical multiplier's type, or the step."""
        try:
            self.cp.system(prev.u + 1e-3 * prev.tangent, prev.critical)
        except CurveEnded as exc:
            return str(exc)
        except _STEP_FAILURES:
            return "the orbit could not be integrated further"
        if self.cp.kind == NEIMARK_SACKER and abs(prev.tests["r4"]) > 0.98:
            return _pair_turned_real(prev.critical)
        return "step-too-small"

    def _edge(self, prev: CurvePoint, u: np.ndarray) -> CurvePoint | None:
        """The point on the crossed bound of either parameter, corrected with that parameter fixed."""
        n = self.cp.n
        for k, (lo, hi) in enumerate(self.bounds):
            lam = float(u[n + k] * self.cp.lam_scales[k])
            if lo <= lam <= hi:
                continue
            edge = lo if lam < lo else hi
            target = edge / self.cp.lam_scales[k]
            if abs(prev.u[n + k] - target) < 1e-12:
                return None
            frac = (target - prev.u[n + k]) / (u[n + k] - prev.u[n + k])
            guess = prev.u + frac * (u - prev.u)
            normal = np.zeros(u.size)
            normal[n + k] = 1.0
            corrected, ok, _ = self.correct(guess, normal, prev.critical)
            if not ok:
                return None
            try:
                return self.make_point(corrected, prev.tangent, prev.critical, prev.vector)
            except (*_STEP_FAILURES, CurveEnded):
                return None
        return None

    def _events(self, prev: CurvePoint, new: CurvePoint, ds: float) -> list[CurvePoint]:
        """Located codimension-two points (and turns) between ``prev`` and ``new``, in arclength order."""
        found = []
        for name, before in prev.tests.items():
            after = new.tests.get(name)
            if name == "ns_outside" or after is None or not (math.isfinite(before) and math.isfinite(after)):
                continue
            if np.sign(before) == np.sign(after) or before == 0.0:
                continue
            if name == "ns_others" and prev.tests["ns_outside"] == new.tests["ns_outside"]:
                continue  # a neutral saddle of two other real multipliers, no bifurcation
            located = self.locate(prev, new, name, ds)
            if located is not None:
                located.event = event_name(name, self.cp.kind, self.names)
                found.append(located)
        return sorted(found, key=lambda p: float(np.linalg.norm(p.u - prev.u)))

    def locate(self, prev: CurvePoint, new: CurvePoint, test: str, ds: float) -> CurvePoint | None:
        """Regula falsi (Illinois) on the arclength for the zero of ``test`` between ``prev`` and ``new``."""
        lo, hi, f_lo, f_hi = 0.0, float(np.linalg.norm(new.u - prev.u)), prev.tests[test], new.tests[test]
        best, side = new, 0
        for _ in range(40):
            if hi - lo < self.settings.locate_tol:
                break
            s = falsi_point(lo, hi, f_lo, f_hi)
            u, ok, _ = self.correct(prev.u + s * prev.tangent, prev.tangent, prev.critical)
            if not ok:
                return best if hi - lo < 0.1 * ds else None
            try:
                best = self.make_point(u, prev.tangent, prev.critical, prev.vector)
            except (*_STEP_FAILURES, CurveEnded):
                return None
            f = best.tests[test]
            if f == 0.0:
                break
            lo, hi, f_lo, f_hi, side = illinois_update(lo, hi, f_lo, f_hi, s, f, side)
        return best

    @staticmethod
    def reverse(point: CurvePoint) -> CurvePoint:
        """``point`` heading the other way (its turn tests change sign with the tangent)."""
        tests = point.tests | {"turn1": -point.tests["turn1"], "turn2": -point.tests["turn2"]}
        return CurvePoint(
            **{**point.__dict__, "tangent": -point.tangent, "tests": tests, "event": "", "step": math.nan}
        )

    def restore(
        self, u: np.ndarray, tangent: np.ndarray, critical: complex, vector: np.ndarray, step: float = math.nan
    ) -> CurvePoint:
        """A stored point recomputed (a resumed march goes on from it along ``tangent`` with ``step``)."""
        point = self.make_point(np.asarray(u, dtype=float), np.asarray(tangent, dtype=float), critical, vector)
        point.step = step
        return point

    def run(self, x0: np.ndarray, lam1: float, lam2: float, reference: complex) -> Curve:
        """Start at ``(x0, lam1, lam2)``, march towards ``bounds2[1]`` first, then the other way."""
        start = self.start(x0, lam1, lam2, reference)
        ahead, ahead_end = self.march(start)
        back, back_end = self.march(self.reverse(start))
        return Curve(self.cp.kind, list(back)[::-1] + [start] + list(ahead), [back_end, ahead_end])
