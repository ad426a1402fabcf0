"""Fixed-step RK4 of the emulated (complete) system, Eq. (11).

State ``z = (y, ydot, theta, thetadot)``; parameters are the float64 vector of
:meth:`pendsweep.model.params.ModelParams.kernel_array`. The step is chosen so that
a forcing period holds an integer number of steps, which makes the
stroboscopic (Poincare) section exact; the forcing values at the RK4 stage
times are then periodic and come from a precomputed half-step table.
"""

import math

import numba as nb
import numpy as np

from ._layout import (
    N_RECORD_COLUMNS,
    P_C,
    P_K,
    P_K3,
    P_M,
    STATUS_DIVERGED,
    STATUS_OK,
    pendulum_params,
)
from ._records import TWO_PI, record_close, record_open, record_sample, wrap_index
from ._rhs import signum
from ._steps import eq11_rk4


@nb.njit(cache=True, nogil=True, inline="always")
def eq11_params(p, sgn_per_stage, vector):
    """The parameter tuple of :func:`eq11_rhs` from a kernel parameter vector ``p``.

    ``sgn_per_stage`` evaluates sgn(thetadot) at every RK4 stage instead of
    once per step; ``vector`` (a constant at every call site) selects the
    vectorisable formulation (see :func:`eq11_rhs`).
    """
    m, l, b1, b2, b3, g = pendulum_params(p)
    return (m, l, b1, b2, b3, g, p[P_M], p[P_C], p[P_K], p[P_K3], sgn_per_stage, vector, 1.0 / l, 1.0 / m)


@nb.njit(cache=True, nogil=True, inline="always")
def eq11_step(x, f0, fh, f1, dt, q):
    """One RK4 step of Eq. (11) from state tuple ``x``; forcing f0, fh, f1 at t, t + dt/2, t + dt.

    ``q`` is :func:`eq11_params`. Unless ``q`` asks for it per stage, the
    signum of thetadot is taken once at the start of the step and held
    across the stages, as in the paper.
    """
    s0 = signum(x[3])
    return eq11_rk4(x, (f0, s0), (fh, s0), (f1, s0), dt, q)


@nb.njit(cache=True, nogil=True)
def forcing_table(alpha, steps_per_period):
    """alpha sin(2 pi t/T) at the 2n half-step times of one period of n steps."""
    n2 = 2 * steps_per_period
    table = np.empty(n2 + 1, dtype=np.float64)
    for k in range(n2 + 1):
        table[k] = alpha * math.sin(math.pi * k / steps_per_period)
    return table


@nb.njit(cache=True, nogil=True)
def emulated_periods(state, p, alpha, fe, steps_per_period, transient_periods, sgn_per_stage, out):
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
    q = eq11_params(p, sgn_per_stage, False)
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
            y, yd, th, thd = eq11_step((y, yd, th, thd), table[2 * j], table[2 * j + 1], table[2 * j + 2], dt, q)
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
    q = eq11_params(p, sgn_per_stage, False)
    y, yd, th, thd = state[0], state[1], state[2], state[3]
    out[0, 0], out[0, 1], out[0, 2], out[0, 3], out[0, 4] = 0.0, y, yd, th, thd
    status = STATUS_OK
    k = 0
    for _ in range(n_periods):
        for j in range(n):
            y, yd, th, thd = eq11_step((y, yd, th, thd), table[2 * j], table[2 * j + 1], table[2 * j + 2], dt, q)
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
