"""Kernels that replay a measured record: a fixed-pivot pendulum, Eq. (11)
driven by a recorded force array, and the substructuring loop driven by it.

Both integrate with classical RK4 at the record's sample step and write one
row per sample, so simulated and measured channels align index by index.
"""

import math

import numba as nb
import numpy as np

from ._actuator import hermite
from ._emulated import eq11_params, eq11_step
from ._layout import P_B1, P_B2, P_B3, P_G, P_K, P_K3, P_L, P_M_PEND, STATUS_DIVERGED, STATUS_OK
from ._rhs import signum
from ._steps import model_rk4, pivot_pendulum_rk4
from ._substructured import interface_momentum


@nb.njit(cache=True, nogil=True, inline="always")
def _pendulum_params(p):
    """``m, l, b1, b2, b3, g`` from the kernel parameter vector."""
    return p[P_M_PEND], p[P_L], p[P_B1], p[P_B2], p[P_B3], p[P_G]


@nb.njit(cache=True, nogil=True)
def pendulum_trace(state, p, dt, substeps, out):
    """Free swing of the pendulum about a fixed pivot.

    Parameters
    ----------
    state : float64[2]
        ``(theta [rad], thetadot [rad/s])`` at the first sample.
    p : float64[10]
        Parameter vector (``ModelParams.kernel_array``); only m, l, b1-b3, g are used.
    dt : float
        Sample step [s].
    substeps : int
        RK4 steps per sample; sgn(thetadot) is held over each step, as in the
        paper, which makes the Coulomb term depend on the step size.
    out : float64[n, 2]
        Filled with ``theta, thetadot`` at every sample, row 0 being ``state``.

    Returns
    -------
    int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    """
    m, l, b1, b2, b3, g = _pendulum_params(p)
    h = dt / substeps
    th, thd = state[0], state[1]
    out[0, 0], out[0, 1] = th, thd
    for i in range(1, out.shape[0]):
        for _ in range(substeps):
            # Eq. (2) with a fixed pivot: the platform acceleration is zero.
            q = (signum(thd), m, l, b1, b2, b3, g)
            th, thd = pivot_pendulum_rk4((th, thd), 0.0, 0.0, 0.0, h, q)
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
    q = eq11_params(p, False, False)
    for i in range(1, out.shape[0]):
        y, yd, th, thd = eq11_step(
            (y, yd, th, thd), gain * force[i - 1], gain * force_half[i - 1], gain * force[i], dt, q
        )
        if not (math.isfinite(y) and math.isfinite(yd) and math.isfinite(th) and math.isfinite(thd)):
            out[i:, :] = np.nan
            return STATUS_DIVERGED
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = y, yd, th, thd
    return STATUS_OK


@nb.njit(cache=True, nogil=True, inline="always")
def _delayed_command(cmd, cmdd, k, r, tau, dt):
    """Hermite interpolant of the command samples at ``t_k + r - tau``: x, x', x''."""
    q = k + (r - tau) / dt
    if q <= 0.0:
        return cmd[0], cmdd[0], 0.0
    # Segment [j, j + 1] with q in (j, j + 1], so t_k + dt never needs sample k + 2. The
    # tolerance absorbs rounding of q at a sample; j >= 0, or a q within it of 0 (a delay that
    # is a whole number of samples) would index cmd[-1], the end of the record.
    j = max(math.ceil(q - 1e-9) - 1, 0)
    return hermite(cmd[j], cmdd[j], cmd[j + 1], cmdd[j + 1], q - j, dt)


@nb.njit(cache=True, nogil=True)
def substructured_replay(
    state, p, M1, C1, M2, C2, force, force_half, gain, gain_fs, tau, dt, substeps, cmd, cmdd, k0, out, fs_start=math.nan
):
    """The substructuring loop driven by a recorded F_e, with x(t) = y_cmd(t - tau).

    Each tick follows :func:`pendsweep.kernels._substructured.substructured_loop`
    with the ``"delay"`` actuator, no prediction and no filter: the load cell
    reads the mean of Eq. (4) over the last tick (a momentum difference) times
    ``gain_fs``; Eq. (3) ``M1 y'' + C1 y' + K y + k3 y^3 = gain F_e - F_s`` takes
    one RK4 step with that force held; the command for the next tick is
    ``y*``; the pendulum on the platform follows ``x(t) = c(t - tau)``, the
    cubic Hermite interpolant of the commands, in ``substeps`` RK4 substeps.

    Parameters
    ----------
    state : float64[4]
        ``(y* [m], y*' [m/s], theta [rad], thetadot [rad/s])`` at sample 0 of ``out``.
    p : float64[10]
        ``ModelParams.kernel_array()`` (m, l, b1-b3, g, K, k3 are used).
    M1, C1, M2, C2 : float
        Numerical and platform mass [kg] and damping [kg/s].
    force, force_half : float64[N], float64[N - 1]
        Recorded F_e at the record's samples and midway [N].
    gain, gain_fs : float
        Applied force = gain * F_e; measured F_s = gain_fs * true F_s.
    tau : float
        Actuator delay [s].
    dt : float
        Controller tick = sample step [s].
    substeps : int
        Rig RK4 substeps per tick.
    cmd, cmdd : float64[N]
        Command and its slope [m], [m/s] at the record's samples. Entries up to
        ``k0`` hold the measured history (times before the record's start take
        its first value); later entries are overwritten with the simulated commands.
    k0 : int
        Record sample at which this segment starts.
    out : float64[n, 4]
        Filled with ``x [m], theta [rad], F_s measured [N], y_cmd [m]`` per sample.
    fs_start : float, optional
        Load-cell reading at sample ``k0`` [N], fed back over the first tick. A
        segment started inside a record passes the measured value: the reading
        is the mean force over the tick before ``k0``, which needs the pendulum's
        state there. NaN (default): computed from ``state`` with the pendulum
        term held over that tick (exact for a pendulum at rest).

    Returns
    -------
    int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    """
    m, l, b1, b2, b3, g = _pendulum_params(p)
    model = (M1, C1, p[P_K], p[P_K3])
    ms = M2 + m
    h = dt / substeps
    ys, yds, th, thd = state[0], state[1], state[2], state[3]
    n = out.shape[0]
    x, xd, _a = _delayed_command(cmd, cmdd, k0, -dt, tau, dt)
    mom_prev = interface_momentum(xd, x, thd * math.sin(th), ms, C2, m, l)
    for i in range(n):
        k = k0 + i
        x, xd, _a = _delayed_command(cmd, cmdd, k, 0.0, tau, dt)
        mom = interface_momentum(xd, x, thd * math.sin(th), ms, C2, m, l)
        f_fb = gain_fs * (mom - mom_prev) / dt
        if i == 0 and math.isfinite(fs_start):
            f_fb = fs_start
        mom_prev = mom
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = x, th, f_fb, cmd[k]
        if i == n - 1:
            break
        # Eq. (3), force held over the tick.
        f0 = gain * force[k] - f_fb
        fh = gain * force_half[k] - f_fb
        f1 = gain * force[k + 1] - f_fb
        ys, yds = model_rk4((ys, yds), f0, fh, f1, dt, model)
        cmd[k + 1], cmdd[k + 1] = ys, yds
        # Rig: the pendulum on the platform moving as the delayed command.
        for sub in range(substeps):
            r0 = sub * h
            a1 = _delayed_command(cmd, cmdd, k, r0, tau, dt)[2]
            a2 = _delayed_command(cmd, cmdd, k, r0 + 0.5 * h, tau, dt)[2]
            a4 = _delayed_command(cmd, cmdd, k, r0 + h, tau, dt)[2]
            th, thd = pivot_pendulum_rk4((th, thd), a1, a2, a4, h, (signum(thd), m, l, b1, b2, b3, g))
        if not (math.isfinite(ys) and math.isfinite(th) and math.isfinite(thd)):
            out[i + 1 :, :] = np.nan
            return STATUS_DIVERGED
    return STATUS_OK
