"""Many parameter points integrated in lockstep, vectorised across points.

The scalar kernel (:func:`pendsweep.kernels.emulated_periods`) spends its
time in libm ``sin``/``cos``, which LLVM cannot vectorise. Here the state of
a chunk of points lives in structure-of-arrays form and the innermost loop
runs over points, so that LLVM turns one RK4 step of the whole chunk into
AVX-512 code; ``sin``/``cos`` come from the branch-free
:func:`~pendsweep.kernels._sincos.sincos_poly`. The forcing at the stage
times is the scalar kernel's half-step table when all points of a chunk
share their steps per period, and otherwise the exact phase of each step's
start (``sincos_poly``) followed by two half-step rotations. Each point
keeps its own step, so points with different ``fe`` (and so different steps
per period) share a chunk; a point that has finished or diverged is frozen
by a select. Period ends are rare events handled by a scalar pass that fills
the same records as the scalar kernel.

Chunks run in parallel (``prange``). A point's result depends on the other
points of its chunk only through whether they all share its steps per period
(then the forcing comes from the scalar kernel's exact table).
"""

import math

import numba as nb
import numpy as np

from ._emulated import eq11_step, forcing_table
from ._layout import (
    N_PARAMS,
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
    REC_THETA_ABSMAX,
    REC_THETA_PEAK,
    REC_Y_ABSMAX,
    STATUS_DIVERGED,
    STATUS_OK,
)
from ._records import TWO_PI, fold_extremes, record_close, wrap_index
from ._sincos import sincos_poly

# Rows of a chunk's per-point constant table: the parameter vector, then these.
_ALPHA, _ROT_S, _ROT_C, _STEPS, _DT, _INV_L, _INV_M = range(N_PARAMS, N_PARAMS + 7)
_N_CONST = N_PARAMS + 7


# error_model="numpy": no ZeroDivisionError branch (every denominator is > 0),
# which would keep LLVM from vectorising the loop. The loop writes only six
# arrays: more would exceed LLVM's budget of runtime alias checks.
@nb.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def _step_chunk(y, yd, th, thd, peak, yabs, live, const, k, sgn_per_stage, uniform, u0, u1, u2):
    """Advance every live point of a chunk by RK4 step ``k`` (0-based, float).

    ``y, yd, th, thd`` are the state, ``peak`` the signed wrapped theta of
    largest modulus and ``yabs`` the max |y| of the current period (all
    float64[n], updated in place); ``live`` is 1.0 for points still being
    integrated; ``const`` is float64[_N_CONST, n]. When every point has the
    same steps per period (``uniform``), ``u0, u1, u2`` are the unit forcing
    sines at the step's stage times, shared by all points.
    """
    for i in range(y.shape[0]):
        a = const[_ALPHA, i]
        if uniform:
            s0, s1, s2 = u0, u1, u2
        else:
            # Forcing at the stage times t, t + dt/2, t + dt: the exact phase of the
            # step's start (the scalar kernel's table argument), then two half-step rotations.
            n = const[_STEPS, i]
            rs = const[_ROT_S, i]
            rc = const[_ROT_C, i]
            s0, c0 = sincos_poly(math.pi * (2.0 * (k - n * np.floor(k / n))) / n)
            s1 = s0 * rc + c0 * rs
            c1 = c0 * rc - s0 * rs
            s2 = s1 * rc + c1 * rs
        y0, yd0, th0, thd0, pk0, ya0 = y[i], yd[i], th[i], thd[i], peak[i], yabs[i]
        q = (
            const[P_M_PEND, i], const[P_L, i], const[P_B1, i], const[P_B2, i], const[P_B3, i],
            const[P_G, i], const[P_M, i], const[P_C, i], const[P_K, i], const[P_K3, i],
            sgn_per_stage, True, const[_INV_L, i], const[_INV_M, i],
        )  # fmt: skip
        y1, yd1, th1, thd1 = eq11_step((y0, yd0, th0, thd0), a * s0, a * s1, a * s2, const[_DT, i], q)
        _, pk1, ya1 = fold_extremes(abs(pk0), pk0, ya0, y1, th1)
        on = live[i] != 0.0
        y[i] = y1 if on else y0
        yd[i] = yd1 if on else yd0
        th[i] = th1 if on else th0
        thd[i] = thd1 if on else thd0
        peak[i] = pk1 if on else pk0
        yabs[i] = ya1 if on else ya0


@nb.njit(cache=True, nogil=True)
def _integrate_chunk(state, p, alpha, fe, steps, transient_periods, sgn_per_stage, out, status, done):
    """Integrate one chunk of points (all arrays are the chunk's slices); see :func:`batched_periods`."""
    n = state.shape[1]
    total = transient_periods + out.shape[1]
    y = state[0].copy()
    yd = state[1].copy()
    th = state[2].copy()
    thd = state[3].copy()
    peak = np.zeros(n)
    yabs = np.zeros(n)
    live = np.ones(n)
    period = np.zeros(n, dtype=np.int64)
    period_end = np.empty(n, dtype=np.int64)  # step count at the end of each point's current period
    const = np.empty((_N_CONST, n))
    max_steps = 0
    uniform = True
    for i in range(n):
        uniform = uniform and steps[i] == steps[0]
        const[:N_PARAMS, i] = p[:, i]
        const[_ALPHA, i] = alpha[i]
        const[_ROT_S, i] = math.sin(math.pi / steps[i])
        const[_ROT_C, i] = math.cos(math.pi / steps[i])
        const[_STEPS, i] = steps[i]
        const[_DT, i] = 1.0 / (fe[i] * steps[i])
        const[_INV_L, i] = 1.0 / p[P_L, i]
        const[_INV_M, i] = 1.0 / p[P_M_PEND, i]
        period_end[i] = steps[i]
        _, peak[i], yabs[i] = fold_extremes(0.0, 0.0, 0.0, y[i], th[i])  # the opening sample
        status[i] = STATUS_OK
        done[i] = total
        max_steps = max(max_steps, total * steps[i])
    # Unit forcing sines at the half-step times (as in the scalar kernel), for a uniform chunk.
    table = forcing_table(1.0, steps[0])
    next_end = period_end.min()
    for k in range(max_steps):
        j = k % steps[0]
        _step_chunk(
            y, yd, th, thd, peak, yabs, live, const, float(k), sgn_per_stage,
            uniform, table[2 * j], table[2 * j + 1], table[2 * j + 2],
        )
        if k + 1 < next_end:
            continue
        next_end = max_steps + 1
        for i in range(n):
            if period_end[i] != k + 1:
                next_end = min(next_end, period_end[i])
                continue
            period_end[i] += steps[i]
            next_end = min(next_end, period_end[i])
            if live[i] == 0.0:
                continue
            kp = period[i]
            r = kp - transient_periods
            if not (math.isfinite(y[i]) and math.isfinite(yd[i]) and math.isfinite(th[i]) and math.isfinite(thd[i])):
                if r >= 0:
                    out[i, r, :] = np.nan
                status[i] = STATUS_DIVERGED
                done[i] = kp
                live[i] = 0.0
                continue
            # Net passes over the top in this period; rewrapping keeps theta bounded.
            turns = wrap_index(th[i])
            th[i] -= TWO_PI * turns
            if r >= 0:
                row = out[i, r]
                row[REC_THETA_PEAK] = peak[i]
                row[REC_THETA_ABSMAX] = abs(peak[i])
                row[REC_Y_ABSMAX] = yabs[i]
                record_close(row, y[i], yd[i], th[i], thd[i], turns)
            period[i] = kp + 1
            if kp + 1 == total:
                live[i] = 0.0
            _, peak[i], yabs[i] = fold_extremes(0.0, 0.0, 0.0, y[i], th[i])
        if live.max() == 0.0:
            break
    state[0, :] = y
    state[1, :] = yd
    state[2, :] = th
    state[3, :] = thd


@nb.njit(cache=True, nogil=True, parallel=True)
def batched_periods(state, p, alpha, fe, steps, transient_periods, sgn_per_stage, bounds, out, status, done):
    """Integrate whole forcing periods of many points and fill per-period records.

    Point ``i`` is integrated as ``emulated_periods`` would with
    ``state[:, i]``, ``p[:, i]``, ``alpha[i]``, ``fe[i]``, ``steps[i]``, except
    that sin/cos come from :func:`sincos_poly` (<= 1 ulp), divisions become
    reciprocals and, in a chunk whose points differ in ``steps``, the forcing
    sine at the half steps comes from a rotation (a few ulp of ``alpha``).

    Parameters
    ----------
    state : float64[4, n]
        ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])`` per point at
        forcing phase 0 (structure of arrays); overwritten with the final
        states (theta wrapped; a diverged point keeps its non-finite state).
    p : float64[N_PARAMS, n]
        Parameter vectors (``ModelParams.kernel_array``) as columns.
    alpha, fe : float64[n]
        Forcing amplitude [N] and frequency [Hz] per point.
    steps : int64[n]
        RK4 steps per forcing period per point; ``dt = 1 / (fe * steps)``.
        A chunk whose points share ``steps`` shares the forcing values.
    transient_periods : int
        Periods integrated before recording starts.
    sgn_per_stage : bool
        Evaluate sgn(thetadot) at every RK4 stage instead of once per step.
    bounds : int64[n_chunks + 1]
        Chunk ``c`` holds points ``bounds[c]:bounds[c + 1]``, integrated in
        lockstep by one thread; chunks run in parallel.
    out : float64[n, n_record, N_RECORD_COLUMNS]
        Filled with one row per recorded period (see ``_layout``); rows after
        a divergence are left untouched.
    status : int64[n]
        ``STATUS_OK`` or ``STATUS_DIVERGED`` per point.
    done : int64[n]
        Periods completed (transient included) before any divergence.
    """
    for c in nb.prange(bounds.shape[0] - 1):
        lo = bounds[c]
        hi = bounds[c + 1]
        sub = state[:, lo:hi].copy()
        _integrate_chunk(
            sub, np.ascontiguousarray(p[:, lo:hi]), alpha[lo:hi], fe[lo:hi], steps[lo:hi],
            transient_periods, sgn_per_stage, out[lo:hi], status[lo:hi], done[lo:hi],
        )
        state[:, lo:hi] = sub
