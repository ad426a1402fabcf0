"""Phase margins and stability switches of the delayed loop, Eqs. (8)-(9).

The closed-loop characteristic equation is ``1 + L(s) e^{-s tau} = 0`` with
``L = F_s N_m = (m_s s^2 + C2 s) / (M1 s^2 + C1 s + K)``. A root sits on the
imaginary axis at ``s = i omega`` exactly when ``|L(i omega)| = 1`` (a gain
crossover) and ``omega tau = psi + 2 pi k`` with ``psi = arg L + pi`` the
phase margin, so every stability switch is at ``tau = (psi + 2 pi k)/omega``.
Squaring ``|L| = 1`` gives a quadratic in ``omega^2``:

    (M1^2 - m_s^2) w^4 + (C1^2 - C2^2 - 2 K M1) w^2 + K^2 = 0,

so there are at most two crossovers. The crossing direction does not depend
on ``k``: roots move right as tau grows where ``|L|`` decreases through 1
(``sign Re ds/dtau = -sign d|L|/domega``, Cooke & van den Driessche 1986).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq

from ...model.params import LoopParams

__all__ = [
    "Crossing",
    "DelayMargin",
    "loop_response",
    "gain_crossovers",
    "phase_margins",
    "switch_sequence",
    "delay_margin",
    "stability_chart",
    "numeric_crossings",
    "servo_response",
    "servo_delay_margin",
]


@dataclass(frozen=True)
class Crossing:
    """One gain crossover of the open loop ``L(i omega)``.

    Attributes
    ----------
    omega : float
        Crossover frequency [rad/s], where ``|L| = 1``.
    psi_deg : float
        Phase margin in [0, 360) [deg]: the phase lag that brings ``L`` to -1.
    tau : float
        First delay with a root at ``i omega``, ``psi pi / (180 omega)`` [s];
        the later ones follow every ``2 pi / omega``.
    destabilising : bool
        True where roots cross into the right half-plane as the delay grows.
    """

    omega: float
    psi_deg: float
    tau: float
    destabilising: bool

    @property
    def period(self) -> float:
        """Spacing ``2 pi / omega`` [s] of the repeated switches at this frequency."""
        return 2.0 * math.pi / self.omega


@dataclass(frozen=True)
class DelayMargin:
    """Verdict on the delay a loop tolerates.

    Attributes
    ----------
    verdict : str
        ``"critical"`` (finite ``tau_star``), ``"stable_all_delays"``,
        ``"neutral_unstable"`` (m_s > M1: unstable for every tau > 0) or
        ``"neutral_marginal"`` (m_s = M1).
    reason : str
        One sentence a user can act on.
    tau_star : float or None
        Critical delay [s], the smallest tau with a root on the imaginary axis.
    omega_star : float or None
        Instability (crossing) frequency at ``tau_star`` [rad/s].
    crossings : tuple of Crossing
        All gain crossovers, by increasing frequency.
    """

    verdict: str
    reason: str
    tau_star: float | None = None
    omega_star: float | None = None
    crossings: tuple[Crossing, ...] = field(default_factory=tuple)

    @property
    def has_number(self) -> bool:
        return self.tau_star is not None


def loop_response(loop: LoopParams, omega: np.ndarray | float) -> np.ndarray:
    """Open-loop frequency response ``F_s N_m (i omega)``; shape of ``omega`` [rad/s]."""
    s = 1j * np.asarray(omega, dtype=float)
    return (loop.ms * s * s + loop.C2 * s) / (loop.M1 * s * s + loop.C1 * s + loop.K)


def gain_crossovers(loop: LoopParams) -> np.ndarray:
    """Frequencies [rad/s] with ``|L(i omega)| = 1``, ascending, shape ``(0..2,)``."""
    a = loop.M1**2 - loop.ms**2
    b = loop.C1**2 - loop.C2**2 - 2.0 * loop.K * loop.M1
    c = loop.K**2
    if a == 0.0:
        roots = [-c / b] if b < 0.0 else []
    else:
        disc = b * b - 4.0 * a * c
        if disc < 0.0:
            roots = []
        else:
            # Stable form of the quadratic formula (no cancellation for either root).
            q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
            roots = [q / a, c / q] if q != 0.0 else []
    x = sorted({r for r in roots if r > 0.0})
    return np.sqrt(np.array(x, dtype=float))


def phase_margins(loop: LoopParams) -> tuple[Crossing, ...]:
    """Crossover frequency, phase margin, switch delay and direction at each gain crossover."""
    out = []
    for w in gain_crossovers(loop):
        L = complex(loop_response(loop, w))
        psi = (math.atan2(L.imag, L.real) + math.pi) % (2.0 * math.pi)
        # d|L|^2/d(w^2) has the sign of (|Q|^2)' |P|^2 - |P|^2' |Q|^2 = (|Q|^2)' - (|P|^2)' at |L| = 1.
        x = w * w
        dq = 2.0 * loop.ms**2 * x + loop.C2**2
        dp = 2.0 * loop.M1**2 * x + loop.C1**2 - 2.0 * loop.K * loop.M1
        out.append(Crossing(float(w), math.degrees(psi), psi / w, destabilising=dq - dp < 0.0))
    return tuple(out)


def switch_sequence(loop: LoopParams, tau_max: float) -> list[tuple[float, float, int]]:
    """All imaginary-axis crossings up to ``tau_max`` [s].

    Returns
    -------
    list of (tau [s], omega [rad/s], unstable_pairs_after)
        Sorted by delay; the count starts from 0 (the loop is stable at
        tau = 0 for positive M1, m_s, K and C1 + C2) and moves by one pair at
        each crossing, up where destabilising, down where not.
    """
    events = []
    for c in phase_margins(loop):
        k = 0
        while c.tau + k * c.period <= tau_max:
            events.append((c.tau + k * c.period, c.omega, 1 if c.destabilising else -1))
            k += 1
    events.sort()
    count, out = 0, []
    for tau, w, step in events:
        count = max(count + step, 0)
        out.append((tau, w, count))
    return out


def delay_margin(loop: LoopParams) -> DelayMargin:
    """Critical delay ``tau*`` and its crossing frequency, or why there is none.

    The neutral term decides first: the roots of ``M1 + m_s e^{-s tau} = 0``
    have ``Re s = ln(m_s/M1)/tau``, an infinite chain that the loop's roots
    approach at high frequency. For ``m_s > M1`` it lies in the right
    half-plane for every ``tau > 0``.
    """
    crossings = phase_margins(loop)
    p = loop.mass_ratio
    if loop.ms > loop.M1:
        return DelayMargin(
            "neutral_unstable",
            f"m_s = {loop.ms:g} kg exceeds M1 = {loop.M1:g} kg (p = {p:.4g}): the neutral "
            f"roots of M1 + m_s exp(-s tau) = 0 have Re s = ln(m_s/M1)/tau = {math.log(p):.4g}/tau > 0, "
            "so the loop is unstable for every delay tau > 0",
            crossings=crossings,
        )
    if loop.ms == loop.M1:
        return DelayMargin(
            "neutral_marginal",
            f"m_s = M1 = {loop.M1:g} kg (p = 1): the neutral root chain has Re s -> 0 for every "
            "tau > 0, so no delay is robustly stable; any small increase of m_s destabilises it",
            crossings=crossings,
        )
    destab = [c for c in crossings if c.destabilising]
    if not destab:
        peak = _peak_gain(loop)
        # A double crossover (peak exactly 1) only touches the axis: still no switch.
        bound = "<" if not crossings else "<="
        return DelayMargin(
            "stable_all_delays",
            f"|F_s N_m(i omega)| {bound} 1 at every frequency (its maximum is {peak:.4g}, and "
            f"m_s/M1 = {p:.4g} < 1), so no root crosses the imaginary axis as tau grows: "
            "stable for all delays",
            crossings=crossings,
        )
    first = min(destab, key=lambda c: c.tau)
    return DelayMargin(
        "critical",
        f"a root pair crosses into the right half-plane at tau* = {first.tau:.6g} s, omega* = {first.omega:.6g} rad/s",
        tau_star=first.tau,
        omega_star=first.omega,
        crossings=crossings,
    )


def _peak_gain(loop: LoopParams) -> float:
    """Largest ``|L(i omega)|`` over all frequencies (including omega -> inf)."""
    # |L|^2 is a ratio of quadratics in x = w^2; its stationary points solve a quadratic.
    a1, b1 = loop.ms**2, loop.C2**2  # |Q|^2 = a1 x^2 + b1 x
    a2, b2, c2 = loop.M1**2, loop.C1**2 - 2.0 * loop.K * loop.M1, loop.K**2
    # d/dx (Q/P) = 0  ->  (2 a1 x + b1)(a2 x^2 + b2 x + c2) - (a1 x^2 + b1 x)(2 a2 x + b2) = 0
    poly = [a1 * b2 - b1 * a2, 2.0 * a1 * c2, b1 * c2]
    candidates = [r.real for r in np.roots(poly) if abs(r.imag) < 1e-12 * max(1.0, abs(r)) and r.real > 0]
    values = [abs(complex(loop_response(loop, math.sqrt(x)))) for x in candidates]
    return max(values + [loop.ms / loop.M1])


def stability_chart(omega_n: float, zeta: float, c2_over_c1: float, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fig. 6: maximum delay against mass ratio for one damping case.

    Parameters
    ----------
    omega_n, zeta : float
        Numerical model natural frequency [rad/s] and damping ratio [-].
    c2_over_c1 : float
        Platform damping as a multiple of the model damping [-].
    p : ndarray, shape (n,)
        Mass ratios ``m_s/M1`` [-].

    Returns
    -------
    tau_max, omega : ndarray, shape (n,)
        Critical delay [s] and crossing frequency [rad/s]; ``inf`` where the
        loop is stable for all delays and NaN where it is unstable for every
        delay (p >= 1).
    """
    p = np.asarray(p, dtype=float)
    tau = np.full(p.shape, np.nan)
    omega = np.full(p.shape, np.nan)
    for i, pi in enumerate(p):
        m = delay_margin(LoopParams.from_natural(omega_n, zeta, float(pi), c2_over_c1))
        if m.verdict == "critical":
            tau[i], omega[i] = m.tau_star, m.omega_star
        elif m.verdict == "stable_all_delays":
            tau[i] = np.inf
    return tau, omega


def numeric_crossings(
    response: Callable[[np.ndarray], np.ndarray], omega_min: float, omega_max: float, points: int = 4000
) -> tuple[Crossing, ...]:
    """Gain crossovers, phase margins and switch delays of any open loop ``L0(i omega)``.

    For ``1 + L0(s) e^{-s tau} = 0`` with ``L0`` stable and independent of
    ``tau``: the crossovers are bracketed on a log grid of ``points``
    frequencies in ``[omega_min, omega_max]`` [rad/s] and refined by Brent's
    method; the direction is ``-sign d|L0|/d omega``.
    """
    w = np.geomspace(omega_min, omega_max, points)
    g = np.log(np.abs(response(w)))
    out = []
    for i in np.nonzero(np.sign(g[:-1]) * np.sign(g[1:]) < 0)[0]:
        wc = brentq(lambda x: float(np.log(np.abs(response(np.array([x]))[0]))), w[i], w[i + 1], xtol=1e-13)
        L = complex(response(np.array([wc]))[0])
        psi = (math.atan2(L.imag, L.real) + math.pi) % (2.0 * math.pi)
        out.append(Crossing(wc, math.degrees(psi), psi / wc, destabilising=bool(g[i + 1] < g[i])))
    return tuple(out)


def servo_response(omega: np.ndarray, bandwidth: float, damping: float) -> np.ndarray:
    """``G(i omega) = ws^2/(ws^2 - omega^2 + 2 i zeta ws omega)``, ``ws = 2 pi bandwidth`` [Hz]."""
    ws = 2.0 * math.pi * bandwidth
    return ws * ws / (ws * ws - omega * omega + 2j * damping * ws * omega)


def servo_delay_margin(loop: LoopParams, bandwidth: float, damping: float, hold: float = 0.0) -> DelayMargin:
    """Critical transport delay of ``1 + F_s N_m G(s) e^{-s (tau + hold/2)} = 0`` in continuous time.

    The servo's roll-off makes the loop retarded (no neutral chain), so the
    verdict only depends on the crossovers. ``hold`` [s] adds the zero-order
    hold's mean delay ``hold/2`` (the backend's command DAC); the exact
    sampled-data answer is :func:`pendsweep.analysis.stability.sampled_delay_margin`.
    """
    wn = math.sqrt(loop.K / loop.M1)
    crossings = numeric_crossings(
        lambda w: loop_response(loop, w) * servo_response(w, bandwidth, damping) * np.exp(-0.5j * w * hold),
        1e-3 * wn,
        1e3 * max(wn, 2.0 * math.pi * bandwidth),
    )
    destab = [c for c in crossings if c.destabilising]
    if not destab:
        return DelayMargin(
            "stable_all_delays", "|F_s N_m G| < 1 at every frequency: stable for all delays", crossings=crossings
        )
    first = min(destab, key=lambda c: c.tau)
    return DelayMargin(
        "critical",
        f"with the servo, a root pair crosses at transport delay {first.tau:.6g} s, omega {first.omega:.6g} rad/s",
        tau_star=first.tau,
        omega_star=first.omega,
        crossings=crossings,
    )
