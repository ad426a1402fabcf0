"""Pseudo-arclength continuation of fixed points of a parameter-dependent map, generic.

A *problem* is a map ``P(x; lam)`` of ``R^n`` with its Jacobian (for a forced
system, the stroboscopic map over ``k`` forcing periods and its monodromy
matrix). Its periodic orbits are the zeros of ``G(x, lam) = P(x; lam) - x``.
Nothing here knows about the pendulum: the same code finds the folds of the
forced Duffing oscillator in the tests.

Method (Keller's pseudo-arclength, in scaled variables ``X = x / scale``,
``L = lam / lam_scale``, ``u = (X, L)``):

* tangent ``t`` = unit null vector of ``[G_X  G_L]``, oriented along the march;
* predictor ``u + ds t``; corrector: Newton on ``G = 0`` together with
  ``t . (u - u_pred) = 0``;
* step control: ``ds`` grows by 1.5 after a corrector of at most
  ``fast_iterations`` iterations, halves on failure or when the tangent turns
  by more than ``max_turn`` rad, stops below ``ds_min``.

``G_X`` comes from the problem (variational equations, exact); ``G_L`` is a
central finite difference in the parameter (the one derivative not worth an
extra set of variational equations per parameter; it only enters the
corrector's bordered row and the tangent).

Stability and bifurcations come from the Floquet multipliers ``mu`` (the
eigenvalues of ``dP/dx``) through test functions that change sign at the
bifurcation, evaluated at every accepted point:

=================  ==================================  ============================
event              test function                       condition
=================  ==================================  ============================
fold (mu = +1)     ``det(dP/dx - I)``                  the tangent's ``lam``
                                                       component changes sign too
period doubling    ``det(dP/dx + I)``                  (a real multiplier at -1)
Neimark-Sacker     ``prod_{i<j} (mu_i mu_j - 1)``      a complex pair crosses the
                                                       unit circle
=================  ==================================  ============================

A real multiplier crossing +1 where the parameter does not turn back is
reported as a ``branch-point`` (another branch crosses there, e.g. a
symmetry-breaking pitchfork of the symmetric swing); it is not followed.
Both tests compare signs only, so the verdict does not depend on the
interval (``lam_scale``). The Neimark-Sacker test function also vanishes
at a neutral saddle (a real pair with ``mu_1 mu_2 = 1``), which is no
bifurcation: an event is kept only when the number of complex multipliers
outside the unit circle changes across the step and the located point
has a complex multiplier of modulus 1 (to :data:`NS_MODULUS_TOL`).

A sign change is located by regula falsi (Illinois) on the arclength
between the two points, each trial point corrected onto the branch, to
``locate_tol`` in scaled arclength. At a period doubling the branch of
``P^2`` is entered (branch switching) by solving ``G_2 = 0`` with the
component along the critical eigenvector fixed at ``switch_offset``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .algebra import _Scaled, falsi_point, illinois_update, newton, null_tangent, test_functions
from .problem import (
    _STEP_FAILURES,
    BRANCH_POINT,
    CLOSED,
    COMPLEX_IMAG,
    FOLD,
    LOCATE_ITERATIONS,
    LOCATE_RETRIES,
    NEIMARK_SACKER,
    NS_MODULUS_TOL,
    PERIOD_DOUBLING,
    REACHED,
    Bifurcation,
    Branch,
    ContinuationError,
    EvaluationFailed,
    MapProblem,
    Point,
    Result,
    Settings,
)


# -- the continuation ---------------------------------------------------------------
class Continuation:
    """Continue fixed points of ``problem`` within ``bounds`` of the parameter.

    Use :meth:`run` (start point, both directions, branch switching).
    """

    def __init__(
        self,
        problem: MapProblem,
        bounds: tuple[float, float],
        settings: Settings | None = None,
        progress: Callable[[int], None] | None = None,
    ):
        self.problem = problem
        self.settings = settings or Settings()
        self.bounds = (min(bounds), max(bounds))
        #: +1 or -1: the first march heads from ``bounds[0]`` towards ``bounds[1]`` (a decreasing
        #: interval continues downward first, as with a negative ``ds`` in BifurcationKit).
        self.direction = 1.0 if bounds[1] >= bounds[0] else -1.0
        self.progress = progress or (lambda n: None)

    # .. corrections ..
    def correct_fixed(self, scaled: _Scaled, x0: np.ndarray, lam: float):
        """Newton in ``x`` at fixed ``lam``; returns ``(x, converged, updates)``."""
        s = scaled.problem.scale

        def fun(X):
            r, a, _ = scaled.residual_and_jacobian(np.append(X, lam / scaled.problem.lam_scale), with_lam=False)
            return r, a[:, :-1]

        X, ok, updates = newton(fun, x0 / s, self.settings.newton_tol, self.settings.max_iterations)
        return X * s, ok, updates

    def correct_arclength(self, scaled: _Scaled, u_pred: np.ndarray, normal: np.ndarray, max_iterations: int = 0):
        """Newton on ``G(u) = 0, normal . (u - u_pred) = 0``; returns ``(u, converged, iterations)``.

        ``max_iterations`` (default ``settings.max_iterations``) is raised
        when locating bifurcations, where Newton may be only linear.
        """
        max_iterations = max_iterations or self.settings.max_iterations

        def fun(u):
            r, a, _ = scaled.residual_and_jacobian(u)
            return np.append(r, normal @ (u - u_pred)), np.vstack([a, normal])

        try:
            u, ok, updates = newton(fun, u_pred, self.settings.newton_tol, max_iterations)
        except _STEP_FAILURES:
            return u_pred, False, max_iterations
        return u, ok, len(updates)

    def make_point(self, scaled: _Scaled, u: np.ndarray, previous_tangent: np.ndarray) -> Point:
        _, a, ev = scaled.residual_and_jacobian(u)
        x, lam = scaled.unpack(u)
        return Point(x, lam, np.linalg.eigvals(ev.jacobian), null_tangent(a, previous_tangent), ev.info)

    def _in_bounds(self, lam: float) -> bool:
        lo, hi = self.bounds
        span = hi - lo
        return lo - 1e-12 * span <= lam <= hi + 1e-12 * span

    # .. one direction ..
    def march(self, scaled: _Scaled, start: Point, branch: int, found: list[Bifurcation]) -> tuple[list[Point], str]:
        """Points from ``start`` (excluded) along ``start.tangent`` until a bound, a failure or ``max_points``."""
        st = self.settings
        ds = st.ds
        prev = start
        points: list[Point] = []
        lo, hi = self.bounds
        on_bound = min(abs(start.lam - lo), abs(start.lam - hi)) <= 1e-12 * (hi - lo)
        if on_bound and not self._in_bounds(start.lam + st.ds_min * start.tangent[-1] * scaled.problem.lam_scale):
            return points, "range"  # started on a bound, heading out of the interval
        while len(points) < st.max_points:
            u_prev = scaled.pack(prev.x, prev.lam)
            u_pred = u_prev + ds * prev.tangent
            u, ok, iterations = self.correct_arclength(scaled, u_pred, prev.tangent)
            # A correction as long as the step itself has left the branch (e.g. for the mirror image
            # of a small swing, which is another fixed point of P^2 nearby).
            ok = ok and float(np.linalg.norm(u - u_pred)) <= st.max_correction * ds
            if ok:
                lam = scaled.unpack(u)[1]
                if not self._in_bounds(lam):
                    end = self._end_point(scaled, prev, u, lam)
                    if end is not None:
                        located, stop = self._detect(scaled, prev, end, branch, found, ds)
                        points += located
                        if stop is not None:
                            return points, stop
                        points.append(end)
                        self.progress(1)
                    return points, "range"
                try:
                    # Oriented along the secant, not the old tangent: across a sharp fold the tangent
                    # turns by more than 90 degrees, and the turn check below must see that.
                    new = self.make_point(scaled, u, u - u_prev)
                except _STEP_FAILURES:
                    ok = False
            if ok and math.acos(min(1.0, float(new.tangent @ prev.tangent))) > st.max_turn and ds > st.ds_min:
                ok = False
            if ok and self._jumped_to_image(scaled, prev, new):
                lam_turns = np.sign(prev.tangent[-1]) != np.sign(new.tangent[-1])
                merge = self._merge_point(scaled, prev, new, branch, found, ds, lam_turns)
                if merge is not None:
                    return points + [merge], REACHED
                ok = False
            if not ok:
                ds *= 0.5
                if ds < st.ds_min:
                    if scaled.problem.subperiod_distance(prev.x, prev.info) < 1e-4:
                        return points, REACHED  # shrunk onto the orbit of half the period
                    return points, "step-too-small"
                continue
            located, stop = self._detect(scaled, prev, new, branch, found, ds)
            points += located
            if stop is not None:
                return points, stop
            points.append(new)
            self.progress(1)
            if len(points) > 2 and self._passes(start, prev, new, scaled):
                points.append(start)
                return points, CLOSED
            prev = new
            if iterations <= st.fast_iterations:
                ds = min(st.ds_max, 1.5 * ds)
        return points, "max-points"

    @staticmethod
    def _jumped_to_image(scaled: _Scaled, prev: Point, new: Point) -> bool:
        """Whether ``new`` lies nearer another section point of ``prev``'s orbit than ``prev`` itself.

        A ``k``-periodic orbit is ``k`` fixed points of ``P^k``; for a small
        swing the images (e.g. the mirror image half a period on) are close,
        and a step may land on another one's branch. The march must then
        take a shorter step.
        """
        p = scaled.problem
        d_lam = (new.lam - prev.lam) / p.lam_scale
        to_image = math.hypot(p.image_distance(prev.info, new.x), d_lam)
        return to_image < float(np.linalg.norm(scaled.pack(new.x, new.lam) - scaled.pack(prev.x, prev.lam)))

    @staticmethod
    def _passes(start: Point, prev: Point, new: Point, scaled: _Scaled) -> bool:
        """Whether the step ``prev -> new`` passes ``start`` going the same way (the branch is a closed curve)."""
        a, b, c = (scaled.pack(p.x, p.lam) for p in (prev, new, start))
        chord = b - a
        length = float(np.linalg.norm(chord))
        along = float((c - a) @ chord) / length**2
        if not 0.0 <= along <= 1.0:
            return False
        distance = float(np.linalg.norm(c - a - along * chord))
        return distance < 0.25 * length and float(start.tangent @ new.tangent) > 0.9

    def _end_point(self, scaled: _Scaled, prev: Point, u: np.ndarray, lam: float) -> Point | None:
        """The point exactly at the crossed bound, interpolated then corrected at fixed parameter."""
        edge = self.bounds[0] if lam < self.bounds[0] else self.bounds[1]
        if abs(edge - prev.lam) <= 1e-12 * (self.bounds[1] - self.bounds[0]):
            return None  # the march started on this bound and left it
        frac = (edge - prev.lam) / (lam - prev.lam)
        x_guess = prev.x + frac * (scaled.unpack(u)[0] - prev.x)
        try:
            x, ok, _ = self.correct_fixed(scaled, x_guess, edge)
            return self.make_point(scaled, scaled.pack(x, edge), prev.tangent) if ok else None
        except _STEP_FAILURES:
            return None

    # .. events ..
    def _detect(self, scaled, prev: Point, new: Point, branch: int, found: list[Bifurcation], ds: float):
        """Locate the bifurcations between ``prev`` and ``new``.

        Returns the located points (to be inserted into the branch before
        ``new``, in arclength order) and ``None``, or a reason to stop when the
        branch has reached an orbit of half its period (then the meeting point
        is the last located point).
        """
        f_prev, f_new = test_functions(prev.multipliers), test_functions(new.multipliers)
        lam_turns = np.sign(prev.tangent[-1]) != np.sign(new.tangent[-1])
        merge = self._merge_point(scaled, prev, new, branch, found, ds, lam_turns)
        if merge is not None:
            return [merge], REACHED
        events = [
            kind for kind in (FOLD, PERIOD_DOUBLING, NEIMARK_SACKER) if np.sign(f_prev[kind]) != np.sign(f_new[kind])
        ]
        located: list[tuple[float, Point]] = []
        for kind in events:
            s_point = self.locate(scaled, prev, kind, ds, f_prev[kind], f_new[kind], new)
            if s_point is None:
                continue
            s, point = s_point
            distance = scaled.problem.subperiod_distance(point.x, point.info)
            if distance < 1e-6:
                return [p for _, p in sorted(located, key=lambda e: e[0])] + [point], REACHED
            if kind == FOLD and not lam_turns:
                kind = BRANCH_POINT  # det(P' - I) = 0 where the parameter does not turn back: another branch crosses
            if kind == NEIMARK_SACKER and not self._complex_pair_crosses(
                prev.multipliers, new.multipliers, point.multipliers
            ):
                continue  # e.g. a neutral saddle (real pair with mu1 mu2 = 1)
            vector = None
            if kind == PERIOD_DOUBLING:
                w, v = np.linalg.eig(scaled.problem.evaluate(point.x, point.lam).jacobian)
                vector = np.real(v[:, np.argmin(np.abs(w + 1.0))])
            if any(self._same(b, kind, branch, point, scaled) for b in found):
                continue  # the same point again (a test function flickering at its zero)
            found.append(Bifurcation(kind, point.lam, branch, point.x, point.multipliers, vector))
            located.append((s, point))
        return [p for _, p in sorted(located, key=lambda e: e[0])], None

    @staticmethod
    def _same(b: Bifurcation, kind: str, branch: int, point: Point, scaled: _Scaled) -> bool:
        if b.kind != kind or b.branch != branch:
            return False
        return bool(np.linalg.norm(scaled.pack(b.x, b.lam) - scaled.pack(point.x, point.lam)) < 1e-6)

    def _merge_point(
        self, scaled, prev: Point, new: Point, branch: int, found: list[Bifurcation], ds: float, lam_turns: bool
    ) -> Point | None:
        """The period doubling where a doubled branch ends, if it ends between ``prev`` and ``new``.

        A doubled branch meets the orbit of half its period at a period
        doubling of that orbit, where it turns back in the parameter (the
        vertex of the pitchfork of ``P^2k``) or where the corrector lands on
        the half-period orbit itself. The corrector cannot converge at the
        vertex (a branch point), so the meeting point is recognised as a
        known period doubling of the parent within two steps of both points.
        """
        if scaled.problem.period == 1:
            return None
        on_parent = scaled.problem.subperiod_distance(new.x, new.info) < 1e-6
        if not (lam_turns or on_parent):
            return None
        u_prev, u_new = scaled.pack(prev.x, prev.lam), scaled.pack(new.x, new.lam)
        for index, bif in enumerate(found):
            if (
                bif.kind != PERIOD_DOUBLING
                or index == self._origins.get(branch)
                or self._periods[bif.branch] * 2 != scaled.problem.period
            ):
                continue
            u_pd = scaled.pack(bif.x, bif.lam)
            if max(np.linalg.norm(u_pd - u_prev), np.linalg.norm(u_pd - u_new)) <= 2.0 * ds:
                return self.make_point(scaled, u_pd, prev.tangent)
        return None

    @staticmethod
    def _complex_pair_crosses(before: np.ndarray, after: np.ndarray, located: np.ndarray) -> bool:
        """Whether a complex-conjugate pair of multipliers crosses the unit circle (a Neimark-Sacker point).

        The number of complex multipliers outside the circle must differ
        between the step's ends ``before`` and ``after``, and the ``located``
        point must have a complex multiplier on the circle.
        """

        def outside(mu: np.ndarray) -> int:
            return int(np.sum((np.abs(mu.imag) > COMPLEX_IMAG) & (np.abs(mu) > 1.0)))

        complex_mu = located[np.abs(located.imag) > COMPLEX_IMAG]
        on_circle = complex_mu.size > 0 and float(np.abs(np.abs(complex_mu) - 1.0).min()) < NS_MODULUS_TOL
        return outside(before) != outside(after) and on_circle

    def locate(self, scaled: _Scaled, prev: Point, kind: str, ds: float, f0: float, f1: float, new: Point):
        """Regula falsi (Illinois) on the arclength ``s`` in ``(0, ds)`` for the zero of test function ``kind``.

        Returns ``(s, point)``, or ``None`` when trial points cannot be
        corrected. The bordered Jacobian is singular at a branch point, and
        Newton converges only linearly next to it: a trial that fails is
        replaced by the midpoint between it and a bracket end (alternately),
        which shrinks the bracket, up to :data:`LOCATE_RETRIES` times; a
        failure inside a bracket narrower than a tenth of the step returns
        the bracket end with the smaller test function.
        """

        def value(pt):
            return test_functions(pt.multipliers)[kind]

        u_prev = scaled.pack(prev.x, prev.lam)
        lo, hi, f_lo, f_hi = 0.0, ds, f0, f1
        best, s = new, ds
        ends = {0.0: (abs(f0), prev), ds: (abs(f1), new)}  # bracket ends: |test function|, point
        side, failures, retry = 0, 0, None
        for _ in range(60):
            if hi - lo < self.settings.locate_tol:
                break
            s = falsi_point(lo, hi, f_lo, f_hi)
            if retry is not None:
                s, retry = retry, None
            if not (lo < s < hi):
                s = 0.5 * (lo + hi)
            u, ok, _ = self.correct_arclength(scaled, u_prev + s * prev.tangent, prev.tangent, LOCATE_ITERATIONS)
            try:
                best = self.make_point(scaled, u, prev.tangent) if ok else None
            except _STEP_FAILURES:
                best = None
            if best is None:
                failures += 1
                if failures <= LOCATE_RETRIES and hi - lo > self.settings.locate_tol:
                    retry = 0.5 * (lo + s) if failures % 2 else 0.5 * (s + hi)
                    continue
                if hi - lo > 0.1 * ds:
                    return None
                s = min((lo, hi), key=lambda e: ends[e][0])
                return s, ends[s][1]
            f = value(best)
            ends[s] = (abs(f), best)
            if f == 0.0:
                break
            lo, hi, f_lo, f_hi, side = illinois_update(lo, hi, f_lo, f_hi, s, f, side)
        return s, best

    # .. start, both directions, branch switching ..
    def start(self, scaled: _Scaled, x0: np.ndarray, lam0: float) -> Point:
        """Newton at fixed ``lam0`` from ``x0``; the tangent points towards ``bounds[1]`` (:attr:`direction`)."""
        try:
            x, ok, updates = self.correct_fixed(scaled, x0, lam0)
        except EvaluationFailed as exc:
            raise ContinuationError(f"the start orbit cannot be integrated: {exc}") from None
        if not ok:
            raise ContinuationError(
                f"Newton did not converge at the start ({scaled.problem.period}-period orbit, parameter {lam0:g}); "
                f"last updates {', '.join(f'{v:.1e}' for v in updates[-3:])}: give a start closer to an orbit"
            )
        e = np.zeros(scaled.n + 1)
        e[-1] = self.direction
        return self.make_point(scaled, scaled.pack(x, lam0), e)

    def branch_both_ways(self, scaled: _Scaled, start: Point, index: int, found: list[Bifurcation]) -> Branch:
        """Both directions from ``start``, merged in increasing-arclength order."""
        ahead, ahead_end = self.march(scaled, start, index, found)
        if ahead_end == CLOSED:
            return Branch(scaled.problem.period, [start] + ahead, [CLOSED, CLOSED])
        backward_start = Point(start.x, start.lam, start.multipliers, -start.tangent, start.info)
        back, back_end = self.march(scaled, backward_start, index, found)
        return Branch(scaled.problem.period, back[::-1] + [start] + ahead, [back_end, ahead_end])

    def run(self, x0: np.ndarray, lam0: float) -> Result:
        """Start at ``(x0, lam0)``, continue both ways, switch at period doublings up to ``max_period``."""
        found: list[Bifurcation] = []
        self._periods = [self.problem.period]  # per branch index
        self._origins: dict[int, int] = {}  # branch index -> index in found of its period doubling
        scaled = _Scaled(self.problem, self.settings)
        start = self.start(scaled, x0, lam0)
        branches = [self.branch_both_ways(scaled, start, 0, found)]
        problems = [self.problem]
        handled = 0
        while handled < len(found):
            bif = found[handled]
            handled += 1
            parent = problems[bif.branch]
            if bif.kind != PERIOD_DOUBLING or 2 * parent.period > self.settings.max_period:
                continue
            if any(self._ends_at(b, bif, parent) for b in branches):
                continue  # a doubled branch already runs from another period doubling into this one
            child = parent.with_period(2 * parent.period)
            self._periods.append(child.period)
            self._origins[len(branches)] = handled - 1
            entered = self.enter_doubled(_Scaled(child, self.settings), bif, parent)
            if entered is None:
                branches.append(
                    Branch(child.period, [], ["branch switching failed"], f"period doubling at {bif.lam:.6g}")
                )
                problems.append(child)
                continue
            scaled_child, first, pd_point = entered
            index = len(branches)
            points, end = self.march(scaled_child, first, index, found)
            branches.append(
                Branch(
                    child.period,
                    [pd_point, first] + points,
                    ["period doubling", end],
                    f"period doubling at {bif.lam:.6g}",
                )
            )
            problems.append(child)
        return Result(branches, found, start)

    @staticmethod
    def _ends_at(branch: Branch, bif: Bifurcation, parent: MapProblem) -> bool:
        """Whether ``branch`` (of twice the parent's period) ends at the period doubling ``bif``."""
        if branch.period != 2 * parent.period or not branch.points or branch.ends[-1] != REACHED:
            return False
        end = branch.points[-1]
        close = np.abs((end.x - bif.x) / parent.scale).max() < 1e-4
        return bool(close and abs(end.lam - bif.lam) <= 1e-6 * max(abs(bif.lam), parent.lam_scale))

    def enter_doubled(self, scaled: _Scaled, bif: Bifurcation, parent: MapProblem):
        """The period-doubling point and the first point of the doubled branch, or ``None``."""
        st = self.settings
        v = bif.critical_vector / scaled.problem.scale
        v /= np.linalg.norm(v)
        u_star = scaled.pack(bif.x, bif.lam)
        normal = np.append(v, 0.0)
        u_pred = u_star + st.switch_offset * normal
        u, ok, _ = self.correct_arclength(scaled, u_pred, normal)
        if not ok:
            return None
        try:
            first = self.make_point(scaled, u, np.append(v, 0.0))
            pd_point = self.make_point(scaled, u_star, np.append(v, 0.0))
        except _STEP_FAILURES:
            return None
        if scaled.problem.subperiod_distance(first.x, first.info) < 1e-6:
            return None  # fell back onto the parent orbit
        return scaled, first, pd_point
