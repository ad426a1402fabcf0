"""Kernels that replay a measured record: a fixed-pivot pendulum, Eq. (11)
driven by a recorded force array, and the substructuring loop driven by it;
and, each on its own, the three parts of a substructured test (the diagnosis's
part replays): the transfer system from command to platform motion
(:func:`transfer_trace`), the physical substructure driven by the platform's
motion (:func:`platform_trace`) and the numerical model driven by the
measured force (:func:`numerical_trace`).

They integrate with classical RK4 at the record's sample step (or a whole
fraction of it) and write one row per sample, so simulated and measured
channels align index by index.
"""

import math

import numba as nb
import numpy as np

from ._actuator import hermite
from ._emulated import eq11_params, eq11_step
from ._layout import P_K, P_K3, STATUS_DIVERGED, STATUS_OK, pendulum_params
from ._rhs import pendulum_acc, servo_acc, signum
from ._steps import model_rk4, pivot_pendulum_rk4
from ._substructured import interface_momentum


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
    m, l, b1, b2, b3, g = pendulum_params(p)
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


@nb.njit(cache=True, nogil=True, inline="always")
def _point_force(x, xd, xdd, th, thd, ms, C2, m, l, b1, b2, b3, g):
    """Eq. (4) at one instant: ``(M2 + m) x'' + C2 x' + m l (theta'' sin theta + theta'^2 cos theta)`` [N]."""
    thdd = pendulum_acc(th, thd, xdd, signum(thd), m, l, b1, b2, b3, g)
    return ms * xdd + C2 * xd + m * l * (thdd * math.sin(th) + thd * thd * math.cos(th))


@nb.njit(cache=True, nogil=True)
def substructured_replay(
    state, p, M1, C1, M2, C2, force, force_half, gain, gain_fs, tau, dt, substeps, cmd, cmdd, k0, out,
    fs_start=math.nan, point=False,
):  # fmt: skip
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
    point : bool, optional
        The load cell samples Eq. (4) at the tick instead of averaging it over
        the last tick (a record's ``daq.load_cell = "point"``): ``(M2 + m) x''
        + C2 x' + m l (theta'' sin theta + theta'^2 cos theta)`` with x'' the
        delayed command's at the tick.

    Returns
    -------
    int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    """
    m, l, b1, b2, b3, g = pendulum_params(p)
    model = (M1, C1, p[P_K], p[P_K3])
    ms = M2 + m
    h = dt / substeps
    ys, yds, th, thd = state[0], state[1], state[2], state[3]
    n = out.shape[0]
    x, xd, _a = _delayed_command(cmd, cmdd, k0, -dt, tau, dt)
    mom_prev = interface_momentum(xd, x, thd * math.sin(th), ms, C2, m, l)
    for i in range(n):
        k = k0 + i
        x, xd, a = _delayed_command(cmd, cmdd, k, 0.0, tau, dt)
        mom = interface_momentum(xd, x, thd * math.sin(th), ms, C2, m, l)
        f_fb = gain_fs * (mom - mom_prev) / dt
        if point:
            f_fb = gain_fs * _point_force(x, xd, a, th, thd, ms, C2, m, l, b1, b2, b3, g)
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


@nb.njit(cache=True, nogil=True, inline="always")
def _actuator_output(order, x, xd, u, ud, udd, rate, zeta):
    """The platform's ``(x, x', x'')`` for actuator ``order`` (0: follows the command ``u`` exactly; 1: first
    order; 2: the servo) from the state ``(x, x')`` and the delayed command ``u, u', u''`` [m, m/s, m/s^2]."""
    if order == 0:
        return u, ud, udd
    if order == 1:
        xd = rate * (u - x)
        return x, xd, rate * (ud - xd)
    return x, xd, servo_acc(x, xd, u, rate * rate, 2.0 * zeta * rate)


@nb.njit(cache=True, nogil=True, inline="always")
def _stored(out, i, x, xd, xdd):
    """Row ``i`` of ``out`` set to ``(x, x', x'')``; False (and the rest NaN) once the motion is not finite."""
    out[i, 0], out[i, 1], out[i, 2] = x, xd, xdd
    if math.isfinite(x) and math.isfinite(xd):
        return True
    out[i:, :] = np.nan
    return False


@nb.njit(cache=True, nogil=True, inline="always")
def _delayed_jerk(cmd, cmdd, k, r, tau, dt):
    """Third time derivative of the command's Hermite interpolant at ``t_k + r - tau`` (constant per segment)."""
    q = k + (r - tau) / dt
    if q <= 0.0:
        return 0.0
    j = max(math.ceil(q - 1e-9) - 1, 0)
    return (12.0 * cmd[j] + 6.0 * dt * cmdd[j] - 12.0 * cmd[j + 1] + 6.0 * dt * cmdd[j + 1]) / (dt * dt * dt)


@nb.njit(cache=True, nogil=True)
def transfer_trace(cmd, cmdd, tau, gain, order, rate, zeta, propagator, dt, per_sample, out, x0=math.nan, v0=0.0):
    """The platform motion a transfer-system model makes of a command record.

    The command enters as ``u = gain * c(t - tau)``, ``c`` the cubic Hermite
    interpolant of the command samples and their slopes (before the record:
    its first value). Models by ``order``: 0, a pure delay ``x = u``; 1, a
    first-order servo ``x' = rate (u - x)``; 2, a second-order servo ``x'' =
    servo_acc(x, x', u)`` with ``rate = ws``. The servos start at rest on their
    input's value and advance exactly for the input's cubic over each output
    row (or from ``(x0, v0)`` when ``x0`` is given: with ``gain = 0``, the
    free response the diagnosis fits the record's initial state with):
    ``(x, x')`` at the next row is ``P (x, x', u, u', u'', u''')`` with
    ``P`` the exact propagator over one row
    (:func:`pendsweep.measured.diagnose.identify.servo_step.servo_propagator`), so the cost does
    not grow with the servo's bandwidth and the acceleration stays smooth.

    Parameters
    ----------
    cmd, cmdd : float64[n]
        Command samples [m] and slopes [m/s].
    tau, gain : float
        Transport delay [s] and static gain [-].
    order : int
        0, 1 or 2.
    rate, zeta : float
        1/T [1/s] (order 1) or ws [rad/s] and damping ratio (order 2).
    propagator : float64[2, 6]
        Over one output row, on ``(x, x', u, u', u'', u''')`` (unused for order 0).
    dt : float
        Sample step [s].
    per_sample : int
        Output rows per sample step (row ``k * per_sample`` is sample ``k``).
    out : float64[(n - 1) * per_sample + 1, 3]
        Filled with x [m], x' [m/s], x'' [m/s^2] at every output row.
    x0, v0 : float, optional
        Initial servo state [m], [m/s] (NaN: at rest on the input's value).

    Returns
    -------
    int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    """
    h = dt / per_sample
    c, cd, cdd = _delayed_command(cmd, cmdd, 0, 0.0, tau, dt)
    x, xd = gain * c, gain * cd
    if order == 1:
        xd = 0.0
    if not math.isnan(x0):
        x, xd = x0, v0
    rows = out.shape[0]
    for i in range(rows):
        k, j = i // per_sample, i % per_sample
        c, cd, cdd = _delayed_command(cmd, cmdd, k, j * h, tau, dt)
        u, ud = gain * c, gain * cd
        x, xd, xdd = _actuator_output(order, x, xd, u, ud, gain * cdd, rate, zeta)
        if not _stored(out, i, x, xd, xdd):
            return STATUS_DIVERGED
        if order == 0 or i == rows - 1:
            continue
        v = xd if order == 2 else 0.0
        x, v = _propagate(propagator, x, v, u, ud, gain * cdd, gain * _delayed_jerk(cmd, cmdd, k, j * h, tau, dt))
        if order == 2:
            xd = v
    return STATUS_OK


@nb.njit(cache=True, nogil=True, inline="always")
def _sampled_command(cmd, t, tau, dt, ramped):
    """The command the actuator received at ``t`` from samples sent ``tau`` earlier: held over each tick
    (zero-order hold) or ramped linearly to the next sample; value [m] and slope [m/s]. At a switch, the
    new value; before the record, its first value; after it, its last."""
    j = int(math.floor((t - tau) / dt + 1e-9))
    n = cmd.shape[0]
    if j < 0:
        return cmd[0], 0.0
    if j >= n - 1:
        return cmd[n - 1], 0.0
    if not ramped:
        return cmd[j], 0.0
    slope = (cmd[j + 1] - cmd[j]) / dt
    return cmd[j] + (t - tau - j * dt) * slope, slope


@nb.njit(cache=True, nogil=True, inline="always")
def _sampled_piece(prop, x, v, cmd, start, length, tau, dt, ramped, gain):
    """The servo over ``[start, start + length]``, a piece on which the sampled command is one line."""
    c, cd = _sampled_command(cmd, start + 0.5 * length, tau, dt, ramped)
    return _propagate(prop, x, v, gain * (c - 0.5 * length * cd), gain * cd, 0.0, 0.0)


@nb.njit(cache=True, nogil=True)
def sampled_transfer_trace(
    cmd, tau, gain, order, rate, zeta, first, second, split, ramped, dt, per_sample, out, x0=math.nan, v0=0.0
):
    """:func:`transfer_trace` for a command held over each tick or ramped linearly between ticks.

    A record's ``daq.command`` (``"held"`` or ``"ramped"``) says how the actuator received the
    command samples; the input ``u = gain * c(t - tau)`` is then a staircase or a broken line
    whose corners fall ``split = tau mod h`` after each output row's start (``h = dt /
    per_sample``). Each row is advanced in two exact pieces, ``first`` over ``split`` and
    ``second`` over ``h - split`` (:func:`pendsweep.measured.diagnose.identify.servo_step.servo_propagator`), with
    the input's line on each; the output rows are as :func:`transfer_trace`'s, the input taken
    with its new value at a switch (a pure delay: x' = u', x'' = 0 between the jumps).

    Parameters
    ----------
    cmd : float64[n]
        Command samples [m].
    tau, gain, order, rate, zeta, dt, per_sample, out, x0, v0
        As :func:`transfer_trace`.
    first, second : float64[2, 6]
        Servo propagators over ``split`` and ``h - split``.
    split : float
        Offset of the command's corners within an output row [s], ``0 <= split < h``.
    ramped : bool
        Linear ramps between the samples; False: each sample held over its tick.

    Returns
    -------
    int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    """
    h = dt / per_sample
    c, cd = _sampled_command(cmd, 0.0, tau, dt, ramped)
    x, xd = gain * c, gain * cd
    if order == 1:
        xd = 0.0
    if not math.isnan(x0):
        x, xd = x0, v0
    rows = out.shape[0]
    for i in range(rows):
        s = i * h
        c, cd = _sampled_command(cmd, s, tau, dt, ramped)
        x, xd, xdd = _actuator_output(order, x, xd, gain * c, gain * cd, 0.0, rate, zeta)
        if not _stored(out, i, x, xd, xdd):
            return STATUS_DIVERGED
        if order == 0 or i == rows - 1:
            continue
        v = xd if order == 2 else 0.0
        if split > 0.0:
            x, v = _sampled_piece(first, x, v, cmd, s, split, tau, dt, ramped, gain)
        x, v = _sampled_piece(second, x, v, cmd, s + split, h - split, tau, dt, ramped, gain)
        if order == 2:
            xd = v
    return STATUS_OK


@nb.njit(cache=True, nogil=True, inline="always")
def _propagate(p, x, v, u, ud, udd, uddd):
    """One exact servo step: ``p`` (2 x 6) on ``(x, x', u, u', u'', u''')``."""
    z = (x, v, u, ud, udd, uddd)
    x_next, v_next = 0.0, 0.0
    for m in range(6):
        x_next += p[0, m] * z[m]
        v_next += p[1, m] * z[m]
    return x_next, v_next


@nb.njit(cache=True, nogil=True)
def platform_trace(state, p, M2, C2, gain_fs, motion, per_sample, dt, substeps, out, point=False, kinked=False):
    """The physical substructure driven by a prescribed platform motion: pendulum angle and load cell.

    The pendulum of Eq. (2) rides a pivot whose acceleration is read from
    ``motion`` (a :func:`transfer_trace` output on ``per_sample = 2 *
    substeps`` rows per sample, so every RK4 stage has its row); the load cell
    reads ``gain_fs`` times the mean interface force of Eq. (4) over the last
    sample step (a momentum difference, as the substructured replay's).

    Parameters
    ----------
    state : float64[2]
        ``(theta [rad], thetadot [rad/s])`` at sample 0 of ``motion``.
    p : float64[10]
        ``ModelParams.kernel_array()`` (m, l, b1-b3, g are used).
    M2, C2 : float
        Platform mass [kg] and damping [kg/s].
    gain_fs : float
        Measured F_s = gain_fs x true F_s.
    motion : float64[rows, 3]
        Platform x, x', x'' from sample 0 on.
    per_sample : int
        Rows of ``motion`` per sample step (``2 * substeps``).
    dt : float
        Sample step [s].
    substeps : int
        Pendulum RK4 steps per sample.
    out : float64[n, 2]
        Filled with theta [rad] and F_s measured [N]; row 0's force is NaN (no
        step before it).
    point : bool, optional
        The load cell samples Eq. (4) at the tick (x'' of ``motion``'s row
        there) instead of averaging it over the last sample step.
    kinked : bool, optional
        The motion's acceleration jumps inside the rows (a command held or ramped over each tick,
        :func:`sampled_transfer_trace`): each RK4 step takes the pivot's mean acceleration over its
        halves from the velocity column, ``a1 = A``, ``a2 = (A + B) / 2``, ``a4 = B``, so that the
        step's velocity change is exact whatever the jump's position (row values would misplace
        it by up to half a step, a drift that the pendulum's parametric resonance amplifies).

    Returns
    -------
    int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    """
    m, l, b1, b2, b3, g = pendulum_params(p)
    ms = M2 + m
    h = dt / substeps
    th, thd = state[0], state[1]
    mom_prev = interface_momentum(motion[0, 1], motion[0, 0], thd * math.sin(th), ms, C2, m, l)
    out[0, 0], out[0, 1] = th, np.nan
    for i in range(1, out.shape[0]):
        base = (i - 1) * per_sample
        for sub in range(substeps):
            r = base + 2 * sub
            q = (signum(thd), m, l, b1, b2, b3, g)
            a1, a2, a4 = motion[r, 2], motion[r + 1, 2], motion[r + 2, 2]
            if kinked:
                a1 = (motion[r + 1, 1] - motion[r, 1]) / (0.5 * h)
                a4 = (motion[r + 2, 1] - motion[r + 1, 1]) / (0.5 * h)
                a2 = 0.5 * (a1 + a4)
            th, thd = pivot_pendulum_rk4((th, thd), a1, a2, a4, h, q)
        if not (math.isfinite(th) and math.isfinite(thd)):
            out[i:, :] = np.nan
            return STATUS_DIVERGED
        row = i * per_sample
        mom = interface_momentum(motion[row, 1], motion[row, 0], thd * math.sin(th), ms, C2, m, l)
        out[i, 0], out[i, 1] = th, gain_fs * (mom - mom_prev) / dt
        if point:
            xs = motion[row]
            out[i, 1] = gain_fs * _point_force(xs[0], xs[1], xs[2], th, thd, ms, C2, m, l, b1, b2, b3, g)
        mom_prev = mom
    return STATUS_OK


@nb.njit(cache=True, nogil=True)
def numerical_trace(state, model, force, force_half, feedback, gain, dt, out, central=False):
    """The numerical model, Eq. (3), driven by the recorded forces: the controller's y* on its own.

    Each tick takes one step of ``M1 y'' + C1 y' + K y + k3 y^3 = gain
    F_e(t) - F_fb[k]``: RK4 with the fed-back force held over the tick, as the
    substructured replay's controller does; or (``central``) the explicit
    central-difference step with the velocity centred, the classic integrator
    of hybrid tests, with both forces taken at the tick: ``(M1/dt^2 +
    C1/(2 dt)) y[k+1] = F[k] - (K - 2 M1/dt^2) y[k] - (M1/dt^2 - C1/(2 dt))
    y[k-1] - k3 y[k]^3``.

    Parameters
    ----------
    state : float64[2]
        ``(y* [m], y*' [m/s])`` at sample 0.
    model : tuple of float
        ``(M1 [kg], C1 [kg/s], K [N/m], k3 [N/m^3])``.
    force, force_half : float64[n], float64[n - 1]
        Recorded F_e at the samples and midway [N].
    feedback : float64[n]
        The force fed back at each tick [N] (the load-cell reading).
    gain : float
        Applied force = gain x F_e.
    dt : float
        Sample step [s].
    out : float64[n, 2]
        Filled with y*, y*' at every sample, row 0 being ``state``.
    central : bool
        Central difference instead of RK4.

    Returns
    -------
    int
        ``STATUS_OK`` or ``STATUS_DIVERGED``.
    """
    M1, C1, K, k3 = model
    ys, yds = state[0], state[1]
    out[0, 0], out[0, 1] = ys, yds
    # Central difference: the step before the first from the state's Taylor expansion.
    f = gain * force[0] - feedback[0]
    ys_prev = ys - dt * yds + 0.5 * dt * dt * (f - C1 * yds - K * ys - k3 * ys * ys * ys) / M1
    lhs = M1 / (dt * dt) + C1 / (2.0 * dt)
    for k in range(out.shape[0] - 1):
        f = feedback[k]
        if central:
            rhs = gain * force[k] - f - (K - 2.0 * M1 / (dt * dt)) * ys - (M1 / (dt * dt) - C1 / (2.0 * dt)) * ys_prev
            ys_next = (rhs - k3 * ys * ys * ys) / lhs
            yds = (ys_next - ys_prev) / (2.0 * dt)
            ys_prev, ys = ys, ys_next
        else:
            u0, uh, u1 = gain * force[k] - f, gain * force_half[k] - f, gain * force[k + 1] - f
            ys, yds = model_rk4((ys, yds), u0, uh, u1, dt, model)
        if not (math.isfinite(ys) and math.isfinite(yds)):
            out[k + 1 :, :] = np.nan
            return STATUS_DIVERGED
        out[k + 1, 0], out[k + 1, 1] = ys, yds
    return STATUS_OK
