"""Closed-form results of the paper used as references by tests and figures."""

from __future__ import annotations

import math

from .params import ModelParams


def linear_amplitude(p: ModelParams) -> float:
    """Steady oscillator amplitude [m] with the pendulum at rest.

    ``alpha / |K - (M + m) omega_e^2 + i C omega_e|``: the pendulum then acts
    as a rigid added mass ``m`` (Eq. (1) with theta = 0).
    """
    w = p.omega_e
    return p.alpha / abs(complex(p.K - (p.M + p.m) * w * w, p.C * w))


def quenching_amplitudes(p: ModelParams) -> tuple[float, float]:
    """``(y1max, y2max)`` of Eq. (10) [m]: semi-trivial and quenched amplitudes.

    ``kappa`` is read as ``C / (M + m)``; the paper prints ``C(M + m)``,
    whose units are wrong. With this reading ``y1max`` equals
    :func:`linear_amplitude`.
    """
    kappa = p.C / (p.M + p.m)
    a = p.alpha / (p.M + p.m)
    we2 = p.omega_e**2
    y1 = a / math.sqrt((p.omega_nm**2 - we2) ** 2 + (kappa * p.omega_e) ** 2)
    y2 = 2.0 * p.l * abs(p.omega_p**2 / we2 - 0.25)
    return y1, y2


def mechanical_energy(p: ModelParams, y, ydot, theta, thetadot):
    """Total mechanical energy [J] of Eqs. (1)-(2) without damping or forcing.

    ``T = (M+m) ydot^2/2 + m l ydot thetadot sin(theta) + m l^2 thetadot^2/2``,
    ``V = K y^2/2 + k3 y^4/4 - m g l cos(theta)``; works on arrays.
    """
    import numpy as np

    s, c = np.sin(theta), np.cos(theta)
    kinetic = 0.5 * (p.M + p.m) * ydot**2 + p.m * p.l * ydot * thetadot * s + 0.5 * p.m * p.l**2 * thetadot**2
    potential = 0.5 * p.K * y**2 + 0.25 * p.k3 * y**4 - p.m * p.g * p.l * c
    return kinetic + potential
