"""Variational equations of Eq. (11): its Jacobian, and the orbit and tangent integrated together.

The stroboscopic map ``P`` of the emulated system is the RK4 flow over whole
forcing periods. Its Jacobian (the monodromy matrix, ``(4, 4)``) comes from
``Phi' = J(x, t) Phi`` integrated alongside the orbit: the augmented state
``(x, Phi, integral of trace J)`` (21 numbers) is advanced by the project's
one RK4 step (:func:`pendsweep.kernels._rk4.make_rk4_step`) over
:func:`variational_rhs`. Classical RK4 commutes with linearisation, so the
matrix integrated this way is the exact derivative of the discrete RK4 map
(to rounding), not an approximation of the continuous monodromy: Newton on
the discrete map converges quadratically to machine precision. The last
component integrates ``trace J`` with the stage weights, so
``det Phi = exp(it)`` to the order of the method (Liouville).

The pendulum damping ``f_d = b1 sgn(w) + b2 w + b3 w^2 sgn(w)`` is not smooth
at ``w = thetadot = 0``. With ``eps > 0`` the sign is ``tanh(w / eps)`` at
every stage, which makes the map smooth; with ``eps = 0`` the sign is held
over each step (the paper's scheme, as in the sweep kernels) and its
derivative taken as zero: that is the map's Jacobian almost everywhere, but
the map is then discontinuous where a step starts at ``w = 0`` with
``b1 > 0`` (docs/continuation.md).

The right-hand side is :func:`pendsweep.kernels._rhs.eq11_rhs`, the one
implementation of Eq. (11), and the damping law its
:func:`~pendsweep.kernels._rhs.pendulum_damping`; only the derivative of
Eq. (11) is written here.
"""

import math

import numba as nb
from numba.extending import overload

from ._emulated import eq11_params, forcing_table
from ._layout import STATUS_DIVERGED, STATUS_OK
from ._records import TWO_PI, record_close, record_open, record_sample, wrap_index
from ._rhs import eq11_rhs, pendulum_damping, signum
from ._rk4 import make_rk4_step

_INLINE = nb.njit(cache=True, nogil=True, inline="always")


@_INLINE
def damping_sign(thd, eps, held):
    """Sign used in ``f_d`` and its derivative with respect to thetadot [s/rad].

    ``tanh(thd / eps)`` and ``(1 - tanh^2) / eps`` for ``eps > 0``; the held
    sign ``held`` (taken at the step's start) and 0 for ``eps = 0``.
    """
    if eps > 0.0:
        t = math.tanh(thd / eps)
        return t, (1.0 - t * t) / eps
    return held, 0.0


@_INLINE
def eq11_jacobian(x, force, sgn, dsgn, q):
    """Jacobian of :func:`eq11_rhs` with respect to ``x = (y, ydot, theta, thetadot)``.

    Parameters
    ----------
    x : 4-tuple
        State [m, m/s, rad, rad/s].
    force : float
        External force at this time [N].
    sgn, dsgn : float
        The sign used in ``f_d`` and its derivative with respect to thetadot
        (:func:`damping_sign`).
    q : tuple
        :func:`pendsweep.kernels._emulated.eq11_params` (only the physical entries are used).

    Returns
    -------
    16-tuple
        ``J`` row-major, ``J[i, j] = d(rhs_i) / d(x_j)`` [SI].
    """
    y, yd, th, thd = x
    m, l, b1, b2, b3, g, M, C, K, k3 = q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7], q[8], q[9]
    s, c = math.sin(th), math.cos(th)
    fd = pendulum_damping(thd, sgn, b1, b2, b3)
    dfd = b2 + b1 * dsgn + b3 * (2.0 * thd * sgn + thd * thd * dsgn)  # d f_d / d thetadot
    inv = 1.0 / (M + m * c * c)
    ddenom = -2.0 * m * c * s  # d(M + m cos^2) / d theta
    common = force - C * yd - K * y - k3 * y * y * y - m * l * thd * thd * c + s * fd / l
    q_y = -K - 3.0 * k3 * y * y
    q_th = m * l * thd * thd * s + c * fd / l
    q_thd = -2.0 * m * l * thd * c + s * dfd / l
    num_y = common + m * g * s * s  # ydd = num_y / denom
    num_t = common + (M + m) * g  # thdd = -(s / l) num_t / denom - fd / (m l^2)
    sl = s / l
    return (
        0.0, 1.0, 0.0, 0.0,
        q_y * inv, -C * inv, (q_th + 2.0 * m * g * s * c) * inv - num_y * ddenom * inv * inv, q_thd * inv,
        0.0, 0.0, 0.0, 1.0,
        -sl * q_y * inv, sl * C * inv,
        -(c / l) * num_t * inv - sl * q_th * inv + sl * num_t * ddenom * inv * inv,
        -sl * q_thd * inv - dfd / (m * l * l),
    )  # fmt: skip


def mat4_mul(a, b):
    """Product of two 4 x 4 matrices stored row-major as 16-tuples."""
    return tuple([sum(a[4 * i + r] * b[4 * r + j] for r in range(4)) for i in range(4) for j in range(4)])


@overload(mat4_mul, inline="always")
def _mat4_mul_overload(a, b):
    terms = ", ".join(
        " + ".join(f"a[{4 * i + r}] * b[{4 * r + j}]" for r in range(4)) for i in range(4) for j in range(4)
    )
    namespace: dict = {}
    exec(f"def mat4_mul_impl(a, b):\n    return ({terms},)\n", namespace)  # noqa: S102 - fixed template
    return namespace["mat4_mul_impl"]


# Not inlined: four inlined copies of this 21-component right-hand side in one step took LLVM
# about 40 s to compile (8 s as a call), for perhaps 25% faster periods (0.3 against 0.4 ms on the
# busy 2-core machine); a continuation integrates a few thousand periods, so the call wins.
@nb.njit(cache=True, nogil=True)
def variational_rhs(x, u, p):
    """Eq. (11) with its variational equation and the trace of its Jacobian.

    Parameters
    ----------
    x : 21-tuple
        ``(y, ydot, theta, thetadot)``, ``Phi`` (16, row-major), ``integral of trace J``.
    u : (F_e [N], held sgn)
        Force at the stage time; the sign of thetadot at the step's start.
    p : (eq11_params, eps)
        Parameters of :func:`eq11_rhs` and the sign smoothing [rad/s].
    """
    q, eps = p
    orbit = x[0:4]
    sgn, dsgn = damping_sign(x[3], eps, u[1])
    jac = eq11_jacobian(orbit, u[0], sgn, dsgn, q)
    return eq11_rhs(orbit, (u[0], sgn), q) + mat4_mul(jac, x[4:20]) + (jac[5] + jac[15],)


variational_rk4 = make_rk4_step(variational_rhs, _INLINE)

_IDENTITY4 = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0)


@nb.njit(cache=True, nogil=True)
def variational_periods(state, phi, p, alpha, fe, steps_per_period, periods, eps, records):
    """Integrate ``periods`` forcing periods of Eq. (11) with its variational equation.

    Parameters
    ----------
    state : float64[4]
        ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])`` at forcing
        phase 0; overwritten with the state after ``periods`` periods (theta
        wrapped to (-pi, pi] after every period, as in the sweep kernels).
    phi : float64[4, 4]
        Output: ``d state_end / d state_start``, the monodromy matrix of ``P^periods``.
    p : float64[N_PARAMS]
        ``ModelParams.kernel_array``.
    alpha, fe : float
        Forcing amplitude [N] and frequency [Hz].
    steps_per_period : int
        RK4 steps per period, ``dt = 1 / (fe * steps_per_period)``.
    periods : int
        Forcing periods to integrate (the ``k`` of ``P^k``).
    eps : float
        Smoothing of ``sgn(thetadot)`` in ``f_d`` [rad/s]; 0 holds the sign per step.
    records : float64[periods, N_RECORD_COLUMNS]
        Per-period records (``_layout``): extremes, the section, rotations.

    Returns
    -------
    status : int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    trace_integral : float
        ``integral of trace J dt`` over the run, with the RK4 stage weights [-].
    """
    n = steps_per_period
    dt = 1.0 / (fe * n)
    table = forcing_table(alpha, n)
    params = (eq11_params(p, False, False), eps)
    x = (state[0], state[1], state[2], state[3]) + _IDENTITY4 + (0.0,)
    for period in range(periods):
        row = records[period]
        record_open(row)
        record_sample(row, x[0], x[2])
        for j in range(n):
            held = signum(x[3])
            x = variational_rk4(x, (table[2 * j], held), (table[2 * j + 1], held), (table[2 * j + 2], held), dt, params)
            record_sample(row, x[0], x[2])
        if not (math.isfinite(x[0]) and math.isfinite(x[1]) and math.isfinite(x[2]) and math.isfinite(x[3])):
            state[0], state[1], state[2], state[3] = x[0], x[1], x[2], x[3]
            return STATUS_DIVERGED, x[20]
        turns = wrap_index(x[2])
        x = x[0:2] + (x[2] - TWO_PI * turns,) + x[3:21]
        record_close(row, x[0], x[1], x[2], x[3], turns)
    state[0], state[1], state[2], state[3] = x[0], x[1], x[2], x[3]
    for i in range(4):
        for j in range(4):
            phi[i, j] = x[4 + 4 * i + j]
    return STATUS_OK, x[20]
