"""Kernels that replay a measured record: a fixed-pivot pendulum and Eq. (11)
driven by a recorded force array.

Both integrate with classical RK4 at the record's sample step and write one
row per sample, so simulated and measured channels align index by index.
"""

import math

import numba as nb
import numpy as np

from ._emulated import emulated_step, signum
from ._layout import P_B1, P_B2, P_B3, P_G, P_L, P_M_PEND, STATUS_DIVERGED, STATUS_OK


@nb.njit(cache=True, nogil=True, inline="always")
def _pendulum_rhs(th, thd, m, l, b1, b2, b3, g, sgn):
    """Eq. (2) with a fixed pivot (ydd = 0): thetadot and thetaddot."""
    fd = b1 * sgn + b2 * thd + b3 * thd * thd * sgn
    return thd, -(g / l) * math.sin(th) - fd / (m * l * l)


@nb.njit(cache=True, nogil=True)
def pendulum_trace(state, p, dt, out):
    """Free swing of the pendulum about a fixed pivot.

    Parameters
    ----------
    state : float64[2]
        ``(theta [rad], thetadot [rad/s])`` at the first sample.
    p : float64[10]
        Parameter vector (``ModelParams.kernel_array``); only m, l, b1-b3, g are used.
    dt : float
        Sample step [s], one RK4 step per sample; sgn(thetadot) is held over
        the step, as in the paper.
    out : float64[n, 2]
        Filled with ``theta, thetadot`` at every sample, row 0 being ``state``.

    Returns
    -------
    int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    """
    m, l, g = p[P_M_PEND], p[P_L], p[P_G]
    b1, b2, b3 = p[P_B1], p[P_B2], p[P_B3]
    h = dt
    h2 = 0.5 * h
    th, thd = state[0], state[1]
    out[0, 0], out[0, 1] = th, thd
    for i in range(1, out.shape[0]):
        s = signum(thd)
        k1t, k1d = _pendulum_rhs(th, thd, m, l, b1, b2, b3, g, s)
        k2t, k2d = _pendulum_rhs(th + h2 * k1t, thd + h2 * k1d, m, l, b1, b2, b3, g, s)
        k3t, k3d = _pendulum_rhs(th + h2 * k2t, thd + h2 * k2d, m, l, b1, b2, b3, g, s)
        k4t, k4d = _pendulum_rhs(th + h * k3t, thd + h * k3d, m, l, b1, b2, b3, g, s)
        th += h / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
        thd += h / 6.0 * (k1d + 2.0 * k2d + 2.0 * k3d + k4d)
        if not (math.isfinite(th) and math.isfinite(thd)):
            out[i:, :] = np.nan
            return STATUS_DIVERGED
        out[i, 0], out[i, 1] = th, thd
    return STATUS_OK


@nb.njit(cache=True, nogil=True)
def driven_trace(state, p, force, force_half, gain, dt, out):
    """Eq. (11) driven by a sampled force, one RK4 step per sample.

    Parameters
    ----------
    state : float64[4]
        ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])`` at sample 0.
    p : float64[10]
        Parameter vector (``ModelParams.kernel_array``).
    force : float64[n]
        Recorded external force F_e at the samples [N].
    force_half : float64[n - 1]
        F_e interpolated at the midpoints between samples [N].
    gain : float
        Applied force = ``gain * force``.
    dt : float
        Sample step [s].
    out : float64[n, 4]
        Filled with the state at every sample, row 0 being ``state``.

    Returns
    -------
    int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    """
    y, yd, th, thd = state[0], state[1], state[2], state[3]
    out[0, 0], out[0, 1], out[0, 2], out[0, 3] = y, yd, th, thd
    for i in range(1, out.shape[0]):
        y, yd, th, thd = emulated_step(
            y, yd, th, thd, gain * force[i - 1], gain * force_half[i - 1], gain * force[i], dt, p, False
        )
        if not (math.isfinite(y) and math.isfinite(yd) and math.isfinite(th) and math.isfinite(thd)):
            out[i:, :] = np.nan
            return STATUS_DIVERGED
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = y, yd, th, thd
    return STATUS_OK
