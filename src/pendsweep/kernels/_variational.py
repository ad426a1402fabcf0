"""Variational equations of Eq. (11): its Jacobian and an RK4 step of orbit plus tangent.

The stroboscopic map ``P`` of the emulated system is the RK4 flow over whole
forcing periods. Its Jacobian (the monodromy matrix, shape ``(4, 4)``) is
obtained by integrating ``Phi' = J(z, t) Phi`` alongside the orbit with the
*same* RK4 stages. Classical RK4 commutes with linearisation, so the matrix
integrated this way is the exact derivative of the discrete map (to rounding),
not an approximation of the continuous monodromy: Newton on the discrete map
then converges quadratically to machine precision.

The pendulum damping ``f_d = b1 sgn(w) + b2 w + b3 w^2 sgn(w)`` is not smooth
at ``w = thetadot = 0``. With ``eps > 0`` the sign is replaced by
``tanh(w / eps)`` at every stage, which makes the map smooth; with
``eps = 0`` the sign is held over each step (the paper's scheme, as in the
sweep kernels) and its derivative is taken as zero, which is the map's
Jacobian almost everywhere but leaves the map discontinuous where a step
starts at ``w = 0`` with ``b1 > 0`` (docs/continuation.md).

The right-hand side is :func:`pendsweep.kernels._emulated.rhs_sc`, the one
implementation of Eq. (11); only its derivative is written here.
"""

import math

import numba as nb
import numpy as np

from ._emulated import forcing_table, rhs_sc, signum
from ._layout import (
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
from ._records import TWO_PI, record_close, record_open, record_sample, wrap_index


@nb.njit(cache=True, nogil=True, inline="always")
def damping_sign(thd, eps, held):
    """Sign used in ``f_d`` and its derivative with respect to thetadot.

    ``tanh(thd / eps)`` and ``(1 - tanh^2) / eps`` for ``eps > 0``; the held
    sign ``held`` (taken at the step's start) and 0 for ``eps = 0``.
    """
    if eps > 0.0:
        t = math.tanh(thd / eps)
        return t, (1.0 - t * t) / eps
    return held, 0.0


@nb.njit(cache=True, nogil=True, inline="always")
def jacobian_sc(y, yd, s, c, thd, force, m, l, b1, b2, b3, g, M, C, K, k3, sgn, dsgn, jac):
    """Jacobian of Eq. (11) with respect to ``(y, ydot, theta, thetadot)``, written into ``jac``.

    Parameters
    ----------
    y, yd, s, c, thd : float
        State with ``s = sin(theta)``, ``c = cos(theta)`` [m, m/s, -, -, rad/s].
    force : float
        External force at this time [N].
    m, l, b1, b2, b3, g, M, C, K, k3 : float
        Model parameters (``ModelParams``; SI).
    sgn, dsgn : float
        The sign used in ``f_d`` and its derivative with respect to thetadot
        [s/rad] (:func:`damping_sign`).
    jac : float64[4, 4]
        Output, ``jac[i, j] = d(rhs_i) / d(z_j)``.

    Returns
    -------
    float
        The trace of ``jac`` [1/s] (Liouville's formula integrates it).
    """
    fd = b1 * sgn + b2 * thd + b3 * thd * thd * sgn
    dfd = b1 * dsgn + b2 + b3 * (2.0 * thd * sgn + thd * thd * dsgn)
    denom = M + m * c * c
    ddenom = -2.0 * m * c * s
    common = force - C * yd - K * y - k3 * y * y * y - m * l * thd * thd * c + s * fd / l
    q_y = -K - 3.0 * k3 * y * y
    q_yd = -C
    q_th = m * l * thd * thd * s + c * fd / l
    q_thd = -2.0 * m * l * thd * c + s * dfd / l
    num_y = common + m * g * s * s  # ydd = num_y / denom
    num_t = common + (M + m) * g  # thdd = -(s / l) num_t / denom - fd / (m l^2)
    inv = 1.0 / denom
    jac[0, 0], jac[0, 1], jac[0, 2], jac[0, 3] = 0.0, 1.0, 0.0, 0.0
    jac[1, 0] = q_y * inv
    jac[1, 1] = q_yd * inv
    jac[1, 2] = (q_th + 2.0 * m * g * s * c) * inv - num_y * ddenom * inv * inv
    jac[1, 3] = q_thd * inv
    jac[2, 0], jac[2, 1], jac[2, 2], jac[2, 3] = 0.0, 0.0, 0.0, 1.0
    sl = s / l
    jac[3, 0] = -sl * q_y * inv
    jac[3, 1] = -sl * q_yd * inv
    jac[3, 2] = -(c / l) * num_t * inv - sl * q_th * inv + sl * num_t * ddenom * inv * inv
    jac[3, 3] = -sl * q_thd * inv - dfd / (m * l * l)
    return jac[1, 1] + jac[3, 3]


@nb.njit(cache=True, nogil=True, inline="always")
def _stage(y, yd, th, thd, force, p, eps, held, jac):
    """Orbit derivative ``(4,)`` at one RK4 stage; fills ``jac`` and returns its trace last."""
    m, l, b1, b2, b3, g = p[P_M_PEND], p[P_L], p[P_B1], p[P_B2], p[P_B3], p[P_G]
    M, C, K, k3 = p[P_M], p[P_C], p[P_K], p[P_K3]
    sgn, dsgn = damping_sign(thd, eps, held)
    s, c = math.sin(th), math.cos(th)
    dy, dyd, dth, dthd = rhs_sc(y, yd, s, c, thd, force, m, l, b1, b2, b3, g, M, C, K, k3, sgn)
    trace = jacobian_sc(y, yd, s, c, thd, force, m, l, b1, b2, b3, g, M, C, K, k3, sgn, dsgn, jac)
    return dy, dyd, dth, dthd, trace


@nb.njit(cache=True, nogil=True, inline="always")
def _tangent_stage(jac, base, prev, a, out):
    """``out = jac @ (base + a * prev)``: one stage of the variational equation (4 x 4; ``out`` not ``prev``)."""
    for i in range(4):
        for j in range(4):
            acc = 0.0
            for r in range(4):
                acc += jac[i, r] * (base[r, j] + a * prev[r, j])
            out[i, j] = acc


@nb.njit(cache=True, nogil=True)
def variational_periods(state, phi, p, alpha, fe, steps_per_period, periods, eps, tangent, records):
    """Integrate ``periods`` forcing periods of Eq. (11) and, optionally, its variational equation.

    Parameters
    ----------
    state : float64[4]
        ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])`` at forcing
        phase 0; overwritten with the state after ``periods`` periods (theta
        wrapped to (-pi, pi] after every period, as in the sweep kernels).
    phi : float64[4, 4]
        Tangent matrix, normally the identity on entry; overwritten with
        ``d state_end / d state_start`` when ``tangent`` is true.
    p : float64[10]
        ``ModelParams.kernel_array``.
    alpha, fe : float
        Forcing amplitude [N] and frequency [Hz].
    steps_per_period : int
        RK4 steps per period, ``dt = 1 / (fe * steps_per_period)``.
    periods : int
        Forcing periods to integrate (the ``k`` of ``P^k``).
    eps : float
        Smoothing of ``sgn(thetadot)`` in ``f_d`` [rad/s]; 0 holds the sign per step.
    tangent : bool
        Integrate ``phi`` too (otherwise ``phi`` is left as it is).
    records : float64[periods, N_RECORD_COLUMNS]
        Per-period records (``_layout``): extremes, the section, rotations.

    Returns
    -------
    status : int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    trace_integral : float
        ``integral of trace J dt`` over the run with the RK4 weights of the
        stages (1, 2, 2, 1)/6 [-]; ``det(phi) = exp(trace_integral)`` to the
        order of the method (Liouville).
    """
    n = steps_per_period
    dt = 1.0 / (fe * n)
    h2 = 0.5 * dt
    w = dt / 6.0
    table = forcing_table(alpha, n)
    jac = np.empty((4, 4))
    k1 = np.empty((4, 4))
    k2 = np.empty((4, 4))
    k3 = np.empty((4, 4))
    k4 = np.empty((4, 4))
    y, yd, th, thd = state[0], state[1], state[2], state[3]
    trace_integral = 0.0
    for period in range(periods):
        row = records[period]
        record_open(row)
        record_sample(row, y, th)
        for j in range(n):
            f0, fh, f1 = table[2 * j], table[2 * j + 1], table[2 * j + 2]
            held = signum(thd)
            ky1, kv1, kt1, kw1, tr1 = _stage(y, yd, th, thd, f0, p, eps, held, jac)
            if tangent:
                _tangent_stage(jac, phi, phi, 0.0, k1)
            ky2, kv2, kt2, kw2, tr2 = _stage(
                y + h2 * ky1, yd + h2 * kv1, th + h2 * kt1, thd + h2 * kw1, fh, p, eps, held, jac
            )
            if tangent:
                _tangent_stage(jac, phi, k1, h2, k2)
            ky3, kv3, kt3, kw3, tr3 = _stage(
                y + h2 * ky2, yd + h2 * kv2, th + h2 * kt2, thd + h2 * kw2, fh, p, eps, held, jac
            )
            if tangent:
                _tangent_stage(jac, phi, k2, h2, k3)
            ky4, kv4, kt4, kw4, tr4 = _stage(
                y + dt * ky3, yd + dt * kv3, th + dt * kt3, thd + dt * kw3, f1, p, eps, held, jac
            )
            if tangent:
                _tangent_stage(jac, phi, k3, dt, k4)
                for r in range(4):
                    for col in range(4):
                        phi[r, col] += w * (k1[r, col] + 2.0 * k2[r, col] + 2.0 * k3[r, col] + k4[r, col])
            y += w * (ky1 + 2.0 * ky2 + 2.0 * ky3 + ky4)
            yd += w * (kv1 + 2.0 * kv2 + 2.0 * kv3 + kv4)
            th += w * (kt1 + 2.0 * kt2 + 2.0 * kt3 + kt4)
            thd += w * (kw1 + 2.0 * kw2 + 2.0 * kw3 + kw4)
            trace_integral += w * (tr1 + 2.0 * tr2 + 2.0 * tr3 + tr4)
            record_sample(row, y, th)
        if not (math.isfinite(y) and math.isfinite(yd) and math.isfinite(th) and math.isfinite(thd)):
            state[0], state[1], state[2], state[3] = y, yd, th, thd
            return STATUS_DIVERGED, trace_integral
        turns = wrap_index(th)
        th -= TWO_PI * turns
        record_close(row, y, yd, th, thd, turns)
    state[0], state[1], state[2], state[3] = y, yd, th, thd
    return STATUS_OK, trace_integral
