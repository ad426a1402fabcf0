"""The semi-trivial solution and its Hopf boundary in closed form and by Floquet theory.

The ``analytic`` and ``floquet`` methods of :mod:`pendsweep.studies.hopf` (see there for the equations):
the oscillator's steady response with the pendulum at rest, Eq. (12), and the largest Floquet
multiplier of the damped Mathieu equation it pumps.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import brentq

from ..errors import ConfigError
from ..kernels._mathieu import mathieu_monodromy
from ..model.params import ModelParams


def fe_for_omega_hat(params: ModelParams, omega_hat: float) -> float:
    """Forcing frequency [Hz] giving ``omega_hat = w_e / (2 w_p)``."""
    return omega_hat * params.omega_p / math.pi


def semi_trivial_response(params: ModelParams) -> complex:
    """Complex amplitude ``Y`` [m] of ``y(t) = Im(Y exp(i w_e t))`` with theta = 0.

    Raises ConfigError for a cubic spring (``k3 != 0``), whose response is
    not a single harmonic.
    """
    if params.k3 != 0.0:
        raise ConfigError(f"k3 = {params.k3:g} N/m^3: the Hopf boundary methods need a linear spring (k3 = 0)")
    w = params.omega_e
    return params.alpha / complex(params.K - (params.M + params.m) * w * w, params.C * w)


def alpha_hopf_analytic(params: ModelParams, omega_e: np.ndarray | None = None) -> float | np.ndarray:
    """Eq. (12): boundary amplitude [N] at ``params.fe`` (``b1, b3`` ignored).

    ``omega_e`` [rad/s], an array, evaluates it at many forcing frequencies at
    once (the other parameters from ``params``); the result is then an array.
    """
    w = params.omega_e if omega_e is None else np.asarray(omega_e, dtype=np.float64)
    total = params.M + params.m
    kappa = params.C / total
    kappa_p = params.b2 / (params.m * params.l**2)
    sigma = (params.omega_nm / w) ** 2 - 1.0
    sigma_p = 2.0 * ((params.omega_p / w) ** 2 - 0.25)
    alpha = params.l * w * w * total * np.hypot(kappa / w, sigma) * np.hypot(kappa_p / w, sigma_p)
    return float(alpha) if omega_e is None else alpha


def floquet_multipliers(params: ModelParams, steps: int = 200) -> np.ndarray:
    """The two Floquet multipliers (complex, shape ``(2,)``) of theta = 0 at ``params.alpha``."""
    w = params.omega_e
    Y = semi_trivial_response(params)
    # y = Im(Y e^{iwt}) = Re(Y) sin + Im(Y) cos, and y'' = -w^2 y.
    pump = -w * w / params.l
    monodromy = mathieu_monodromy(
        params.g / params.l,
        params.b2 / (params.m * params.l**2),
        pump * Y.real,
        pump * Y.imag,
        w,
        int(steps),
    )
    return np.linalg.eigvals(monodromy)


def hopf_floquet(params: ModelParams, steps: int = 200, alpha_max: float = 500.0) -> dict[str, Any]:
    """Smallest alpha [N] where max |Floquet multiplier| reaches 1.

    A geometric grid (ratio 1.2 from 1e-3 N) finds the first sign change of
    ``log max|mu|``, then brentq refines it to 1e-6 N. Returns a dict with
    ``alpha_H``, ``status`` (``ok`` or ``not-found`` below ``alpha_max``),
    ``multiplier`` (the real part of the critical multiplier: -1 for the
    subharmonic resonance, +1 for the harmonic one) and ``runs`` (monodromy
    evaluations).
    """
    runs = 0

    def log_rho(alpha: float) -> float:
        nonlocal runs
        runs += 1
        return float(np.log(np.abs(floquet_multipliers(params.replace(alpha=alpha), steps)).max()))

    lo, hi = 0.0, 1e-3
    while log_rho(hi) <= 0.0:
        lo, hi = hi, hi * 1.2
        if hi > alpha_max:
            return dict(alpha_H=math.nan, status="not-found", multiplier=math.nan, runs=runs)
    alpha = brentq(log_rho, lo, hi, xtol=1e-6) if lo > 0 else hi
    mu = floquet_multipliers(params.replace(alpha=alpha), steps)
    critical = mu[np.argmax(np.abs(mu))]
    return dict(alpha_H=alpha, status="ok", multiplier=float(critical.real), runs=runs)
