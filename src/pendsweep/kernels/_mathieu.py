"""Monodromy matrix of the damped Mathieu (Hill) equation of the pendulum.

Linearised about the semi-trivial solution (theta = 0, oscillator forced),
Eq. (2) becomes

    theta'' + kappa_p theta' + (omega_p^2 + a(t) / l) theta = 0,

with the pivot acceleration ``a(t) = a_s sin(w t) + a_c cos(w t)`` of the
oscillator's periodic response. The coefficients are evaluated exactly at the
RK4 stage times, so the only error is the RK4 truncation (order 4).
"""

import math

import numba as nb
import numpy as np

from ._steps import mathieu_rk4


@nb.njit(cache=True, nogil=True)
def mathieu_monodromy(omega_p2, kappa_p, pump_sin, pump_cos, omega, steps):
    """Monodromy matrix over one forcing period ``2 pi / omega``.

    Parameters
    ----------
    omega_p2 : float
        Squared pendulum natural frequency g/l [rad^2/s^2].
    kappa_p : float
        Viscous decay coefficient b2 / (m l^2) [1/s].
    pump_sin, pump_cos : float
        Pump ``a(t)/l = pump_sin sin(omega t) + pump_cos cos(omega t)`` [1/s^2].
    omega : float
        Forcing angular frequency [rad/s].
    steps : int
        RK4 steps per period.

    Returns
    -------
    float64[2, 2]
        Columns: ``(theta, thetadot)`` after one period from ``(1, 0)`` and ``(0, 1)``.
    """
    h = 2.0 * math.pi / omega / steps
    out = np.empty((2, 2), dtype=np.float64)
    for col in range(2):
        x = 1.0 if col == 0 else 0.0
        v = 1.0 - x
        for j in range(steps):
            t = j * h
            s0 = omega_p2 + pump_sin * math.sin(omega * t) + pump_cos * math.cos(omega * t)
            th = t + 0.5 * h
            sh = omega_p2 + pump_sin * math.sin(omega * th) + pump_cos * math.cos(omega * th)
            t1 = t + h
            s1 = omega_p2 + pump_sin * math.sin(omega * t1) + pump_cos * math.cos(omega * t1)
            x, v = mathieu_rk4((x, v), s0, sh, s1, h, (kappa_p,))
        out[0, col] = x
        out[1, col] = v
    return out
