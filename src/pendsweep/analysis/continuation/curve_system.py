"""The defining system of a two-parameter bifurcation curve, its gradient, normal forms and test functions.

Used by :mod:`.curves` (the march along the curve).

Defining system
---------------
In scaled variables ``u = (X, L1, L2)`` (``X = x / scale``), ``n + 1``
equations in ``n + 2`` unknowns:

* ``G(x; lam1, lam2) = P^k(x) - x = 0`` (the orbit);
* ``g = 0``, singular where the orbit has the bifurcation:

  - fold and period doubling: ``g`` of the *bordered system* of
    ``M = A - I`` or ``A + I`` (``A = dP^k/dx``),
    ``[[M, b], [c^T, 0]] [v; g] = [0; 1]``, whose ``g`` vanishes exactly
    where ``M`` is singular (Govaerts' minimally augmented system). The
    bordering vectors ``b``, ``c`` are ``M``'s singular vectors of its
    smallest singular value at the last accepted point. This ``g`` is smooth
    however close another multiplier lies (at the semi-trivial solution's
    period doubling the pendulum's pair is -1 and -0.998) and whether or not
    the critical multiplier has a complex twin off the curve; an eigenvalue
    test ``Re mu + 1`` is not. ``dg = -w^T (dA) v`` with ``w`` from the
    transposed system;
  - Neimark-Sacker: ``g = |mu| - 1`` for the complex multiplier nearest the
    previous point's (``Im mu > 0``), ``dmu = w^H (dA) v / (w^H v)`` with its
    right and left eigenvectors ``v``, ``w``.

``(dA) v`` along each unknown is a mixed second difference of ``G``
(:data:`SECOND_STEP`): 4 map evaluations per unknown (8 for a complex
``v``), whatever the state's dimension, so the hybrid loop's 29-slot state
costs no more than a few monodromies. ``G``'s own Jacobian is the
problem's monodromy; its parameter columns are central differences
(one-sided on a parameter's bound, e.g. a delay of 0).

Points where curves end or meet (codimension two)
--------------------------------------------------
Test functions evaluated at every point; a sign change is located by
regula falsi on the arclength, each trial point corrected onto the curve:

=====================  ==================================================  ====================
on a curve of          test function (sign change)                          event
=====================  ==================================================  ====================
any                    tangent's ``lam1`` or ``lam2`` component             ``turn in lam``
fold                   ``a = <p, B(q,q)>/2`` (fold normal form)             ``cusp``
period doubling        ``c = <p, C(q,q,q)>/6 + <p, B(q, r)>/2``,            ``degenerate
                       ``r = (I - A)^-1 B(q,q)``                            period doubling``
any                    ``prod (mu_i - 1)`` over the other multipliers       ``1:1 resonance`` on a
                                                                            fold curve, else
                                                                            ``fold-flip`` /
                                                                            ``fold-Neimark-Sacker``
any                    ``prod (mu_i + 1)`` over the other multipliers       ``1:2 resonance`` on a
                                                                            PD curve, else
                                                                            ``fold-flip`` /
                                                                            ``flip-Neimark-Sacker``
any                    a pair of other multipliers crossing the circle     ``fold-NS``, ``flip-NS``,
                                                                            ``double NS``
Neimark-Sacker         ``kappa = cos(arg mu)`` through ``-1/2``, ``0``      ``1:3``, ``1:4
                                                                            resonance``
=====================  ==================================================  ====================

``q`` and ``p`` are the bordered system's right and left null vectors
(``A q = mu q``, ``A^T p = mu p``), scaled to ``<p, q> = 1``; ``B`` and ``C`` are the
second and third derivatives of ``P^k`` by central differences of step
:data:`NORMAL_FORM_STEP` (scaled). ``c > 0``: supercritical (the doubled
orbit is born stable on the side where the orbit is unstable). The fold's
``a`` changes sign with ``q``'s orientation, which is kept continuous along
the curve. The meeting points are where the curves of the table's two
types cross (a fold-flip point lies on a fold and a period-doubling
curve). A Neimark-Sacker curve ends where its pair turns real
(``kappa -> +-1``: the 1:1 or 1:2 resonance, where it meets a fold or
period-doubling curve); a fold or period-doubling curve goes through them
(its ``prod`` test over the other multipliers changes sign there).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import scipy.linalg

from .problem import COMPLEX_IMAG, FOLD, NEIMARK_SACKER, PERIOD_DOUBLING, ContinuationError

CURVE_KINDS = (FOLD, PERIOD_DOUBLING, NEIMARK_SACKER)

#: Scaled step of the mixed second differences of the eigenvalue gradient.
SECOND_STEP = 1e-4
#: Scaled step of the normal-form differences (third differences need a longer one).
NORMAL_FORM_STEP = 2e-3


class CurveEnded(Exception):
    """The curve's defining system has no meaning here (its critical multiplier changed type)."""


class CurveProblem:
    """The defining system ``F(u) = (G / scale, g)`` of a ``kind`` curve of ``problem`` in ``(lam1, second)``.

    Parameters
    ----------
    problem : map problem
        Continued in its own ``parameter`` (``lam1``); ``problem.at(second, v)`` fixes the second.
    second : str
        The second parameter.
    kind : str
        ``fold``, ``period-doubling`` or ``neimark-sacker``.
    lam2_scale : float
        Characteristic size of the second parameter [its unit].
    """

    def __init__(self, problem, second: str, kind: str, lam2_scale: float):
        if kind not in CURVE_KINDS:
            raise ValueError(f"unknown curve kind {kind!r}")
        self.problem = problem
        self.second = second
        self.kind = kind
        self.scale = np.asarray(problem.scale, dtype=float)
        self.lam_scales = np.array([problem.lam_scale, lam2_scale], dtype=float)
        self.n = self.scale.size
        self._last = None

    # -- variables ---------------------------------------------------------------------
    def pack(self, x: np.ndarray, lam1: float, lam2: float) -> np.ndarray:
        return np.concatenate([np.asarray(x) / self.scale, np.array([lam1, lam2]) / self.lam_scales])

    def unpack(self, u: np.ndarray) -> tuple[np.ndarray, float, float]:
        lam = u[self.n :] * self.lam_scales
        return u[: self.n] * self.scale, float(lam[0]), float(lam[1])

    def map_at(self, u: np.ndarray, tangent: bool):
        x, lam1, lam2 = self.unpack(u)
        return self._at(lam2).evaluate(x, lam1, tangent=tangent)

    def _at(self, lam2: float):
        """The one-parameter problem at ``lam2``, kept for the last value asked (most evaluations share it)."""
        if self._last is None or self._last[0] != lam2:
            self._last = (lam2, self.problem.at(self.second, lam2))
        return self._last[1]

    def residual(self, u: np.ndarray) -> np.ndarray:
        """Scaled ``G(u)``."""
        return self.map_at(u, False).residual / self.scale

    # -- the critical multiplier ----------------------------------------------------------
    def critical(self, a: np.ndarray, reference: complex) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
        """Index of the critical multiplier among ``eig(a)``, the multipliers and its right and left eigenvectors."""
        mu, left, right = scipy.linalg.eig(a, left=True, right=True)
        eligible = np.arange(mu.size)
        if self.kind == NEIMARK_SACKER:
            eligible = eligible[mu.imag > COMPLEX_IMAG]
            if not eligible.size:
                raise CurveEnded(_pair_turned_real(reference))
        i = int(eligible[np.argmin(np.abs(mu[eligible] - reference))])
        return i, mu, right[:, i], left[:, i]

    def _singular(self, a: np.ndarray) -> np.ndarray:
        """``A - I`` (fold) or ``A + I`` (period doubling), singular on the curve."""
        return a - np.eye(self.n) if self.kind == FOLD else a + np.eye(self.n)

    def set_border(self, a: np.ndarray) -> None:
        """Bordering vectors: the right and left singular vectors of the smallest singular value of ``A -+ I``."""
        left, _, right_t = np.linalg.svd(self._singular(a))
        self.border = (left[:, -1], right_t[-1])

    def bordered(self, a: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """``g`` and the null vectors ``v``, ``w`` of the bordered system of ``M = A -+ I`` (module docstring).

        ``[[M, b], [c^T, 0]] [v; g] = [0; 1]`` and its transpose for ``w``
        (``b^T w = 1``): ``g`` vanishes exactly where ``M`` is singular,
        smoothly, whether or not another multiplier lies close (the
        semi-trivial solution's pendulum pair is -1 and -0.998 at its period
        doubling) or the critical one has a complex twin off the curve.
        """
        if getattr(self, "border", None) is None:
            self.set_border(a)
        b, c = self.border
        k = np.zeros((self.n + 1, self.n + 1))
        k[: self.n, : self.n] = self._singular(a)
        k[: self.n, self.n] = b
        k[self.n, : self.n] = c
        rhs = np.zeros(self.n + 1)
        rhs[-1] = 1.0
        vg = np.linalg.solve(k, rhs)
        wg = np.linalg.solve(k.T, rhs)
        return float(vg[-1]), vg[:-1], wg[:-1]

    def _g_gradient(self, u: np.ndarray, mu: complex, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``dg/du`` (n + 2,) with ``(dA) v`` along each unknown a mixed second difference of ``G``.

        Fold and period doubling (bordered): ``dg = -w^T (dA) v``.
        Neimark-Sacker: the eigenvalue derivative ``dmu = w^H (dA) v / (w^H v)``
        and ``d|mu| = Re(conj(mu) dmu) / |mu|``.
        """
        norm = float(np.linalg.norm(v))
        unit_v = v / norm
        parts = [unit_v.real] if self.kind != NEIMARK_SACKER else [unit_v.real, unit_v.imag]
        h = SECOND_STEP
        grad = np.empty(u.size)
        for j in range(u.size):
            e = np.zeros(u.size)
            e[j] = h
            dav = np.zeros(self.n, dtype=complex)
            for part, unit in zip(parts, (1.0, 1j)):
                d = np.concatenate([part, [0.0, 0.0]]) * h

                def along_v(at: np.ndarray, d=d) -> np.ndarray:
                    return (self.residual(at + d) - self.residual(at - d)) / (2.0 * h)

                dav = dav + unit * _slope(along_v, u, e, h)
            if self.kind != NEIMARK_SACKER:
                grad[j] = -float(w @ dav.real) * norm
            else:
                dmu = (w.conj() @ dav) / (w.conj() @ unit_v)
                grad[j] = (np.conj(mu) * dmu).real / abs(mu)
        return grad

    # -- the system -----------------------------------------------------------------------
    def system(self, u: np.ndarray, reference: complex):
        """``F(u)`` (n + 1,), ``dF/du`` (n + 1, n + 2) and the evaluation's extras.

        The extras are ``(evaluation, A, critical index, multipliers, q, p)``
        with ``q``, ``p`` the right and left (null) vectors of the critical multiplier.
        """
        ev = self.map_at(u, True)
        s = self.scale
        a = ev.jacobian * s[None, :] / s[:, None]
        i, mu, v, w = self.critical(a, reference)
        if self.kind == NEIMARK_SACKER:
            g = float(abs(mu[i]) - 1.0)
        else:
            g, v, w = self.bordered(a)
        jac = np.zeros((self.n + 1, self.n + 2))
        jac[: self.n, : self.n] = a - np.eye(self.n)
        for k in (0, 1):
            h = 1e-6 * max(abs(u[self.n + k]), 1.0)
            e = np.zeros(u.size)
            e[self.n + k] = h
            jac[: self.n, self.n + k] = _slope(self.residual, u, e, h)
        jac[self.n] = self._g_gradient(u, mu[i], v, w)
        f = np.append(ev.residual / s, g)
        return f, jac, (ev, a, i, mu, v, w)

    # -- tests ------------------------------------------------------------------------------
    def normal_form(self, u: np.ndarray, a: np.ndarray, mu_c: complex, q: np.ndarray, p: np.ndarray) -> float:
        """Fold ``a`` or period-doubling ``c`` coefficient (module table); NaN on a Neimark-Sacker curve."""
        if self.kind == NEIMARK_SACKER:
            return math.nan
        q = q.real / np.linalg.norm(q.real)
        p = p.real / (p.real @ q)
        h = NORMAL_FORM_STEP

        def along(vec: np.ndarray, t: float) -> np.ndarray:
            return self.residual(u + np.concatenate([vec, [0.0, 0.0]]) * t)

        g0 = along(q, 0.0)
        bqq = (along(q, h) - 2.0 * g0 + along(q, -h)) / h**2
        if self.kind == FOLD:
            return 0.5 * float(p @ bqq)
        cqqq = (along(q, 2 * h) - 2.0 * along(q, h) + 2.0 * along(q, -h) - along(q, -2 * h)) / (2.0 * h**3)
        r = np.linalg.solve(np.eye(self.n) - a, bqq)
        rn = np.linalg.norm(r)
        if rn == 0.0:
            return float(p @ cqqq) / 6.0
        r_unit = r / rn
        # B(q, r) by polarisation: (B(q + r, q + r) - B(q - r, q - r)) / 4, on the unit r (B is bilinear)
        plus = (along(q + r_unit, h) - 2.0 * g0 + along(q + r_unit, -h)) / h**2
        minus = (along(q - r_unit, h) - 2.0 * g0 + along(q - r_unit, -h)) / h**2
        bqr = 0.25 * (plus - minus) * rn
        return float(p @ cqqq) / 6.0 + 0.5 * float(p @ bqr)

    def tests(self, mu: np.ndarray, i: int, tangent: np.ndarray, normal_form: float) -> dict[str, float]:
        """Test functions of the module table at one point."""
        others = other_multipliers(mu, mu[i], self.kind)
        pairs = [others[a] * others[b] - 1.0 for a in range(others.size) for b in range(a + 1, others.size)]
        out = {
            "turn1": float(tangent[self.n]),
            "turn2": float(tangent[self.n + 1]),
            "fold_others": float(np.prod(others - 1.0).real),
            "flip_others": float(np.prod(others + 1.0).real),
            "ns_others": float(np.prod(pairs).real) if pairs else 1.0,
            "ns_outside": float(np.sum((np.abs(others.imag) > COMPLEX_IMAG) & (np.abs(others) > 1.0))),
        }
        if self.kind == NEIMARK_SACKER:
            kappa = float(mu[i].real / abs(mu[i]))
            out["r3"], out["r4"] = kappa + 0.5, kappa
        else:
            out["normal_form"] = normal_form
        return out


def _slope(fn: Callable[[np.ndarray], np.ndarray], u: np.ndarray, e: np.ndarray, h: float) -> np.ndarray:
    """``dfn/du`` along ``e`` (length ``h``): central, or one-sided where a parameter's range ends (a delay of 0)."""
    from ...errors import PendsweepError

    try:
        return (fn(u + e) - fn(u - e)) / (2.0 * h)
    except PendsweepError:
        return (fn(u + e) - fn(u)) / h


def other_multipliers(mu: np.ndarray, critical: complex, kind: str) -> np.ndarray:
    """The multipliers ``mu`` but the critical one (nearest ``critical``) and, on a Neimark-Sacker curve,
    its conjugate."""
    first = int(np.argmin(np.abs(mu - critical)))
    drop = [first]
    if kind == NEIMARK_SACKER:
        distance = np.abs(mu - np.conj(critical))
        distance[first] = np.inf
        drop.append(int(np.argmin(distance)))
    return np.delete(mu, drop)


def initial_reference(kind: str, multipliers: np.ndarray) -> complex:
    """The critical multiplier to track from a point's ``multipliers``: -1, +1, or the complex one nearest the circle."""
    if kind == PERIOD_DOUBLING:
        return -1.0 + 0j
    if kind == FOLD:
        return 1.0 + 0j
    upper = multipliers[multipliers.imag > COMPLEX_IMAG]
    if not upper.size:
        raise ContinuationError("no complex multiplier at the start: not a Neimark-Sacker point")
    return complex(upper[np.argmin(np.abs(np.abs(upper) - 1.0))])


def _pair_turned_real(reference: complex) -> str:
    kappa = reference.real / abs(reference) if reference else 0.0
    return f"the Neimark-Sacker pair turned real ({'1:1' if kappa > 0 else '1:2'} resonance)"


#: Event names per test function and curve kind.
def event_name(test: str, kind: str, names: tuple[str, str]) -> str:
    if test == "turn1":
        return f"turn in {names[0]}"
    if test == "turn2":
        return f"turn in {names[1]}"
    if test == "normal_form":
        return "cusp" if kind == FOLD else "degenerate period doubling"
    if test == "fold_others":
        return {FOLD: "1:1 resonance", PERIOD_DOUBLING: "fold-flip", NEIMARK_SACKER: "fold-Neimark-Sacker"}[kind]
    if test == "flip_others":
        return {FOLD: "fold-flip", PERIOD_DOUBLING: "1:2 resonance", NEIMARK_SACKER: "flip-Neimark-Sacker"}[kind]
    if test == "ns_others":
        return {
            FOLD: "fold-Neimark-Sacker",
            PERIOD_DOUBLING: "flip-Neimark-Sacker",
            NEIMARK_SACKER: "double Neimark-Sacker",
        }[kind]
    return {"r3": "1:3 resonance", "r4": "1:4 resonance"}[test]
