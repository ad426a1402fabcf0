"""Fixed-step RK4 of the emulated (complete) system, Eq. (11).

State ``z = (y, ydot, theta, thetadot)``; parameters are the float64 vector of
:meth:`pendsweep.params.ModelParams.kernel_array`. The step is chosen so that
a forcing period holds an integer number of steps, which makes the
stroboscopic (Poincare) section exact; the forcing values at the RK4 stage
times are then periodic and come from a precomputed half-step table.
"""

import math

import numba as nb
import numpy as np

from ._layout import (
    N_RECORD_COLUMNS,
    P_B1,
    P_B2,
    P_B3,
    P_C,
    P_G,
    P_K,
    P_K3,
    P_L,
    P_M,
    P_M_PEND,
    STATUS_DIVERGED,
    STATUS_OK,
)
from ._sincos import sincos_poly
from ._records import TWO_PI, record_close, record_open, record_sample, wrap_index


@nb.njit(cache=True, nogil=True, inline="always")
def signum(x):
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


@nb.njit(cache=True, nogil=True, inline="always")
def rhs_sc(y, yd, s, c, thd, force, m, l, b1, b2, b3, g, M, C, K, k3, sgn, vector=False, inv_l=0.0, inv_m=0.0):
    """Right-hand side of Eq. (11) given ``s = sin(theta)``, ``c = cos(theta)``.

    ``vector`` (a constant at every call site) replaces the divisions by
    ``l`` and ``m`` with multiplications by the given ``inv_l = 1/l`` and
    ``inv_m = 1/m``, and the two by the denominator with one reciprocal:
    divisions dominate the cost of the vectorised kernel, while the scalar
    kernel keeps the plain form.
    """
    fd = b1 * sgn + b2 * thd + b3 * thd * thd * sgn
    denom = M + m * c * c
    if vector:
        inv_den = 1.0 / denom
        common = force - C * yd - K * y - k3 * y * y * y - m * l * thd * thd * c + s * fd * inv_l
        ydd = (common + m * g * s * s) * inv_den
        thdd = -(s * inv_l) * (common + (M + m) * g) * inv_den - fd * (inv_l * inv_l * inv_m)
        return yd, ydd, thd, thdd
    common = force - C * yd - K * y - k3 * y * y * y - m * l * thd * thd * c + s * fd / l
    ydd = (common + m * g * s * s) / denom
    thdd = -(s / l) * (common + (M + m) * g) / denom - fd / (m * l * l)
    return yd, ydd, thd, thdd


@nb.njit(cache=True, nogil=True, inline="always")
def emulated_rhs(y, yd, th, thd, force, m, l, b1, b2, b3, g, M, C, K, k3, sgn):
    """Right-hand side of Eq. (11) with f_d evaluated for the given signum."""
    return rhs_sc(y, yd, math.sin(th), math.cos(th), thd, force, m, l, b1, b2, b3, g, M, C, K, k3, sgn)


@nb.njit(cache=True, nogil=True, inline="always")
def _sincos(th, vector):
    if vector:
        return sincos_poly(th)
    return math.sin(th), math.cos(th)


@nb.njit(cache=True, nogil=True, inline="always")
def rk4_step(
    y, yd, th, thd, f0, fh, f1, dt, m, l, b1, b2, b3, g, M, C, K, k3, sgn_per_stage, vector, inv_l=0.0, inv_m=0.0
):
    """One classical RK4 step with scalar parameters; forcing f0, fh, f1 at t, t + dt/2, t + dt.

    With ``sgn_per_stage`` false the signum of thetadot is taken once at the
    start of the step and held across the stages, as in the paper.
    ``vector`` selects the vectorisable formulation: :func:`sincos_poly`
    instead of libm and the reciprocals ``inv_l = 1/l``, ``inv_m = 1/m`` in
    :func:`rhs_sc` (callers pass a constant, so the branches fold away after
    inlining).
    """
    h2 = 0.5 * dt
    s0 = signum(thd)
    s, c = _sincos(th, vector)
    k1y, k1yd, k1t, k1td = rhs_sc(y, yd, s, c, thd, f0, m, l, b1, b2, b3, g, M, C, K, k3, s0, vector, inv_l, inv_m)
    y2, yd2, th2, thd2 = y + h2 * k1y, yd + h2 * k1yd, th + h2 * k1t, thd + h2 * k1td
    sg = signum(thd2) if sgn_per_stage else s0
    s, c = _sincos(th2, vector)
    k2y, k2yd, k2t, k2td = rhs_sc(y2, yd2, s, c, thd2, fh, m, l, b1, b2, b3, g, M, C, K, k3, sg, vector, inv_l, inv_m)
    y3, yd3, th3, thd3 = y + h2 * k2y, yd + h2 * k2yd, th + h2 * k2t, thd + h2 * k2td
    sg = signum(thd3) if sgn_per_stage else s0
    s, c = _sincos(th3, vector)
    k3y, k3yd, k3t, k3td = rhs_sc(y3, yd3, s, c, thd3, fh, m, l, b1, b2, b3, g, M, C, K, k3, sg, vector, inv_l, inv_m)
    y4, yd4, th4, thd4 = y + dt * k3y, yd + dt * k3yd, th + dt * k3t, thd + dt * k3td
    sg = signum(thd4) if sgn_per_stage else s0
    s, c = _sincos(th4, vector)
    k4y, k4yd, k4t, k4td = rhs_sc(y4, yd4, s, c, thd4, f1, m, l, b1, b2, b3, g, M, C, K, k3, sg, vector, inv_l, inv_m)
    w = dt / 6.0
    return (
        y + w * (k1y + 2.0 * k2y + 2.0 * k3y + k4y),
        yd + w * (k1yd + 2.0 * k2yd + 2.0 * k3yd + k4yd),
        th + w * (k1t + 2.0 * k2t + 2.0 * k3t + k4t),
        thd + w * (k1td + 2.0 * k2td + 2.0 * k3td + k4td),
    )


@nb.njit(cache=True, nogil=True, inline="always")
def emulated_step(y, yd, th, thd, f0, fh, f1, dt, p, sgn_per_stage):
    """One classical RK4 step (libm sin/cos); forcing f0, fh, f1 at t, t + dt/2, t + dt.

    With ``sgn_per_stage`` false the signum of thetadot is taken once at the
    start of the step and held across the stages, as in the paper.
    """
    return rk4_step(
        y, yd, th, thd, f0, fh, f1, dt,
        p[P_M_PEND], p[P_L], p[P_B1], p[P_B2], p[P_B3], p[P_G], p[P_M], p[P_C], p[P_K], p[P_K3],
        sgn_per_stage, False,
    )


@nb.njit(cache=True, nogil=True)
def forcing_table(alpha, steps_per_period):
    """alpha sin(2 pi t/T) at the 2n half-step times of one period of n steps."""
    n2 = 2 * steps_per_period
    table = np.empty(n2 + 1, dtype=np.float64)
    for k in range(n2 + 1):
        table[k] = alpha * math.sin(math.pi * k / steps_per_period)
    return table


@nb.njit(cache=True, nogil=True)
def emulated_periods(
    state, p, alpha, fe, steps_per_period, transient_periods, sgn_per_stage, out
):
    """Integrate whole forcing periods and fill per-period records.

    Parameters
    ----------
    state : float64[4]
        ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])`` at forcing
        phase 0; overwritten with the final state (theta wrapped).
    p : float64[10]
        Parameter vector, see ``ModelParams.kernel_array``.
    alpha, fe : float
        Forcing amplitude [N] and frequency [Hz].
    steps_per_period : int
        RK4 steps per forcing period; ``dt = 1 / (fe * steps_per_period)``.
    transient_periods : int
        Periods integrated before recording starts.
    sgn_per_stage : bool
        Evaluate sgn(thetadot) at every RK4 stage instead of once per step.
    out : float64[n_record, N_RECORD_COLUMNS]
        Filled with one row per recorded period (see ``_layout``).

    Returns
    -------
    status : int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    periods_done : int
        Periods completed (transient included) before any divergence.
    """
    n = steps_per_period
    dt = 1.0 / (fe * n)
    table = forcing_table(alpha, n)
    y, yd, th, thd = state[0], state[1], state[2], state[3]
    record_periods = out.shape[0]
    total = transient_periods + record_periods
    for period in range(total):
        r = period - transient_periods
        recording = r >= 0
        if recording:
            row = out[r]
            record_open(row)
            record_sample(row, y, th)
        for j in range(n):
            y, yd, th, thd = emulated_step(
                y, yd, th, thd, table[2 * j], table[2 * j + 1], table[2 * j + 2], dt, p, sgn_per_stage
            )
            if recording:
                record_sample(row, y, th)
        if not (math.isfinite(y) and math.isfinite(yd) and math.isfinite(th) and math.isfinite(thd)):
            state[0], state[1], state[2], state[3] = y, yd, th, thd
            if recording:
                for c in range(N_RECORD_COLUMNS):
                    row[c] = np.nan
            return STATUS_DIVERGED, period
        # Net passes over the top in this period; rewrapping keeps theta bounded.
        turns = wrap_index(th)
        th -= TWO_PI * turns
        if recording:
            record_close(row, y, yd, th, thd, turns)
    state[0], state[1], state[2], state[3] = y, yd, th, thd
    return STATUS_OK, total


@nb.njit(cache=True, nogil=True)
def emulated_trace(state, p, alpha, fe, steps_per_period, n_periods, sgn_per_stage, stride, out):
    """Integrate ``n_periods`` and store every ``stride``-th step in ``out``.

    ``out`` has shape ``(n_periods * steps_per_period // stride + 1, 5)`` with
    columns ``t, y, ydot, theta, thetadot`` (theta unwrapped). ``state`` is
    overwritten with the final state. Returns the status code.
    """
    n = steps_per_period
    dt = 1.0 / (fe * n)
    table = forcing_table(alpha, n)
    y, yd, th, thd = state[0], state[1], state[2], state[3]
    out[0, 0], out[0, 1], out[0, 2], out[0, 3], out[0, 4] = 0.0, y, yd, th, thd
    status = STATUS_OK
    k = 0
    for period in range(n_periods):
        for j in range(n):
            y, yd, th, thd = emulated_step(
                y, yd, th, thd, table[2 * j], table[2 * j + 1], table[2 * j + 2], dt, p, sgn_per_stage
            )
            k += 1
            if k % stride == 0:
                i = k // stride
                out[i, 0] = k * dt
                out[i, 1], out[i, 2], out[i, 3], out[i, 4] = y, yd, th, thd
        if not (math.isfinite(y) and math.isfinite(thd)):
            status = STATUS_DIVERGED
            break
    state[0], state[1], state[2], state[3] = y, yd, th, thd
    return status
