"""Exact characteristic roots of the neutral DDE, Eq. (6).

``M1 y'' + C1 y' + K y + m_s y''(t - tau) + C2 y'(t - tau) = 0`` has the
characteristic function (Eq. (7) with ``s = -i omega``)

    D(s) = M1 s^2 + C1 s + K + (m_s s^2 + C2 s) e^{-s tau}.

With ``x = (y, y')`` it is the neutral system
``d/dt [E x(t) + B x(t - tau)] = A0 x(t) + A1 x(t - tau)``. Its infinitesimal
generator is discretised on ``N + 1`` Chebyshev points of ``[-tau, 0]``
(Breda, Maset & Vermiglio 2005): the derivative rows are the Chebyshev
differentiation matrix and the row at ``theta = 0`` is the splicing
condition, which for a neutral equation gives a generalised eigenproblem.
Each eigenvalue is then polished by Newton's method on ``D(s)`` itself, so
every root returned satisfies the exact equation to machine precision; an
argument-principle count on a rectangle checks that none are missing.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from ...model.params import LoopParams

__all__ = [
    "characteristic",
    "rightmost_roots",
    "spectral_abscissa",
    "count_roots",
    "critical_delay_from_roots",
    "neutral_chain_abscissa",
]


def characteristic(loop: LoopParams, tau: float, s: np.ndarray | complex) -> tuple[np.ndarray, np.ndarray]:
    """``D(s)`` and ``D'(s)`` at complex ``s`` [rad/s]; shapes of ``s``."""
    s = np.asarray(s, dtype=complex)
    e = np.exp(-s * tau)
    q = loop.ms * s * s + loop.C2 * s
    d = loop.M1 * s * s + loop.C1 * s + loop.K + q * e
    dd = 2.0 * loop.M1 * s + loop.C1 + (2.0 * loop.ms * s + loop.C2 - tau * q) * e
    return d, dd


def neutral_chain_abscissa(loop: LoopParams, tau: float) -> float:
    """``ln(m_s/M1)/tau`` [1/s]: the real part the high-frequency roots tend to."""
    return math.log(loop.mass_ratio) / tau


def _cheb(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Chebyshev points ``cos(j pi/n)`` and differentiation matrix (Trefethen 2000)."""
    x = np.cos(np.pi * np.arange(n + 1) / n)
    c = np.ones(n + 1)
    c[0] = c[-1] = 2.0
    c *= (-1.0) ** np.arange(n + 1)
    dx = x[:, None] - x[None, :]
    D = np.outer(c, 1.0 / c) / (dx + np.eye(n + 1))
    D -= np.diag(D.sum(axis=1))
    return x, D


def _generator_eigenvalues(loop: LoopParams, tau: float, n: int) -> np.ndarray:
    """Eigenvalues of the ``2(n+1)``-dimensional discretised generator."""
    _, D = _cheb(n)
    D = D * (2.0 / tau)  # theta = tau (x - 1)/2 maps [-1, 1] onto [-tau, 0]
    dim = 2 * (n + 1)
    A = np.kron(D, np.eye(2))
    Bm = np.eye(dim)
    # Row block 0 (theta = 0): E x'(0) + B x'(-tau) = A0 x(0) + A1 x(-tau).
    A[:2, :] = 0.0
    A[:2, :2] = [[0.0, 1.0], [-loop.K, -loop.C1]]
    A[:2, -2:] = [[0.0, 0.0], [0.0, -loop.C2]]
    Bm[:2, :2] = [[1.0, 0.0], [0.0, loop.M1]]
    Bm[:2, -2:] = [[0.0, 0.0], [0.0, loop.ms]]
    return scipy.linalg.eigvals(A, Bm)


def _newton(loop: LoopParams, tau: float, s0: complex, iters: int = 40) -> complex | None:
    """Newton's method on ``D``; None where it does not converge to a root."""
    s = complex(s0)
    for _ in range(iters):
        with np.errstate(all="ignore"):  # far-left starts overflow exp(-s tau): not a root
            d, dd = characteristic(loop, tau, s)
        if not (np.isfinite(d) and np.isfinite(dd)) or dd == 0.0:
            return None
        step = complex(d / dd)
        s -= step
        if abs(step) <= 1e-13 * max(1.0, abs(s)):
            d, _ = characteristic(loop, tau, s)
            scale = loop.M1 * abs(s) ** 2 + loop.C1 * abs(s) + loop.K
            return s if abs(complex(d)) <= 1e-9 * scale else None
    return None


def _default_nodes(loop: LoopParams, tau: float) -> int:
    """Enough Chebyshev nodes to resolve the crossovers and the first chain roots."""
    w = math.sqrt(loop.K / loop.M1) + 2.0 * math.pi / tau
    return int(min(160, max(24, math.ceil(3.0 * w * tau) + 24)))


def rightmost_roots(loop: LoopParams, tau: float, count: int = 6, nodes: int | None = None) -> np.ndarray:
    """Rightmost characteristic roots of Eq. (6) at delay ``tau`` [s].

    Parameters
    ----------
    loop : LoopParams
    tau : float
        Delay [s], >= 0. At ``tau = 0`` the equation is the ODE
        ``(M1 + m_s) y'' + (C1 + C2) y' + K y = 0``.
    count : int
        Number of roots returned (upper half-plane ones and real ones).
    nodes : int, optional
        Chebyshev nodes; the default resolves frequencies several times the
        model's natural frequency.

    Returns
    -------
    ndarray of complex, shape (<= count,)
        Roots with ``Im s >= 0``, each Newton-polished on ``D(s)``, sorted by
        decreasing real part [1/s].
    """
    if tau < 0.0 or not math.isfinite(tau):
        raise ValueError(f"tau = {tau!r} s must be finite and >= 0")
    if tau == 0.0:
        roots = np.roots([loop.M1 + loop.ms, loop.C1 + loop.C2, loop.K])
        roots = roots[roots.imag >= 0.0]
        return roots[np.argsort(-roots.real)][:count]
    n = nodes or _default_nodes(loop, tau)
    found: list[complex] = []
    for lam in _generator_eigenvalues(loop, tau, n):
        if not np.isfinite(lam) or lam.imag < -1e-9:
            continue
        s = _newton(loop, tau, lam)
        if s is None:
            continue
        s = complex(s.real, abs(s.imag))
        if all(abs(s - r) > 1e-8 * max(1.0, abs(s)) for r in found):
            found.append(s)
    roots = np.array(found, dtype=complex)
    return roots[np.argsort(-roots.real)][:count]


def spectral_abscissa(loop: LoopParams, tau: float) -> float:
    """Largest real part of the spectrum at delay ``tau`` [1/s].

    Includes the neutral chain's limit ``ln(m_s/M1)/tau``, which the
    high-frequency roots approach but a finite computation cannot list.
    """
    roots = rightmost_roots(loop, tau, count=1)
    top = float(roots[0].real) if roots.size else -math.inf
    if tau > 0.0:
        top = max(top, neutral_chain_abscissa(loop, tau))
    return top


def count_roots(loop: LoopParams, tau: float, re_min: float, re_max: float, im_max: float, samples: int = 4000) -> int:
    """Number of roots in ``re_min < Re s < re_max, |Im s| < im_max`` (argument principle).

    The winding of ``D`` along the rectangle is summed from the phase steps
    between ``samples`` points per side; the sides must avoid roots.
    """
    edges = [
        (complex(re_min, -im_max), complex(re_max, -im_max)),
        (complex(re_max, -im_max), complex(re_max, im_max)),
        (complex(re_max, im_max), complex(re_min, im_max)),
        (complex(re_min, im_max), complex(re_min, -im_max)),
    ]
    path = np.concatenate([a + (b - a) * np.linspace(0.0, 1.0, samples, endpoint=False) for a, b in edges])
    path = np.append(path, path[0])
    d, _ = characteristic(loop, tau, path)
    winding = np.sum(np.angle(d[1:] / d[:-1])) / (2.0 * math.pi)
    return int(round(winding))


def critical_delay_from_roots(
    loop: LoopParams, tau_max: float, grid: int = 60, rtol: float = 1e-10
) -> tuple[float, float] | None:
    """Smallest delay where the rightmost root reaches the imaginary axis.

    Independent of the phase-margin formula: scans ``tau`` on ``grid``
    points of ``(0, tau_max]`` for the first sign change of the largest real
    part among the computed roots, then bisects.

    Returns
    -------
    (tau_star [s], omega_star [rad/s]) or None if no crossing below ``tau_max``.
    """

    def top(tau: float) -> complex:
        return complex(rightmost_roots(loop, tau, count=1)[0])

    taus = np.linspace(tau_max / grid, tau_max, grid)
    lo = None
    for tau in taus:
        if top(tau).real >= 0.0:
            hi = float(tau)
            break
        lo = float(tau)
    else:
        return None
    lo = lo if lo is not None else 0.0
    while hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        if top(mid).real >= 0.0:
            hi = mid
        else:
            lo = mid
    return hi, abs(top(hi).imag)
