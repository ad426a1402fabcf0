"""The real-time dynamic substructuring loop: controller, transfer system, virtual rig.

One controller tick ``k`` (time ``t_k = k dt``, forcing phase 0 at ``k = 0``) does:

a. **Sensors** at ``t_k``: load cell
   ``F_meas = Fbar_k + noise_f[k] + sum_j a_j sin(j w_e t_k)`` (j = 3, 5, 7),
   encoder ``theta_x = q_enc round(theta / q_enc)``, LVDT
   ``x_meas = q_x round(x / q_x) + noise_x[k]``. ``Fbar_k`` is the mean of the
   true Eq. (4) force over ``[t_k-1, t_k]`` (an integrating ADC). Because
   ``F_s = dP/dt`` with ``P = (M2 + m) x' + C2 x + m l theta' sin(theta)``, the
   mean is exactly ``(P(t_k) - P(t_k-1)) / dt``. A point sample would be
   ill-posed: the servo's ``x''`` jumps at every command step, and sampling it
   just before the jump feeds back ``-(M2 + m) ws^2 (dt/2) y*'``, a spurious
   negative damping of about 21 kg/s with the default servo.
b. **Force path**: optional band-pass (SOS, direct form II transposed), then
   optional polynomial forward prediction of the filtered force by the
   filter's equivalent delay, giving the fed-back ``F_fb``.
c. **Numerical model**, Eq. (3): one RK4 step of
   ``M1 y'' + C1 y' + K y + k3 y^3 = F_e(t) - F_fb`` over ``[t_k, t_k+1]``,
   ``F_e`` at the RK4 stage times, ``F_fb`` held (the force is therefore
   one step old at the end of the step).
d. **Command**: ``c_k+1`` = least-squares polynomial through the last N values
   of ``y*`` extrapolated by ``tau_hat`` (or ``y*_k+1`` itself without
   prediction), with its time derivative.
e. **Rig** over ``[t_k, t_k+1]`` in ``substeps`` RK4 substeps:

   * servo (code 0): ``x'' = ws^2 (u(t - tau) - x) - 2 zeta ws x'`` where
     ``u`` is the zero-order hold of the commands, ``u = c_k`` on
     ``[t_k, t_k+1)`` (the DAC writes a sample one tick after it was computed);
   * delay / ideal (code 1): ``x(t) = H(t - tau)``, the cubic Hermite
     interpolant of the command samples and their derivatives (``tau = 0``
     for the ideal actuator), so ``x`` and ``x'`` are continuous and ``x''``
     piecewise linear;

   with the pendulum ``m l^2 th'' + f_d(th') + m l (g + x'') sin th = 0``
   (signum of ``th'`` held over a substep). The delayed command is taken at
   each substep's midpoint, so hold and delay are resolved to one substep.

State vector (float64, see :func:`state_offsets`): ``0 y*, 1 y*', 2 theta,
3 theta' (true), 4 x, 5 x', 6 ticks done since the initial state, 7-8 x at
the two previous ticks, 9-11 x', x and theta' sin(theta) at the previous
load-cell sample``, then the command delay line ``c`` (most recent
first), the command derivatives, the ``y*`` history, the filtered-force
history and the filter's ``2 n_sections`` delay registers.
"""

import math

import numba as nb
import numpy as np

from ._emulated import forcing_table, signum
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
    STATUS_UNSTABLE,
)
from ._records import TWO_PI, record_close, record_open, record_sample, wrap_index

ACT_SERVO = 0
ACT_HERMITE = 1

#: Columns of the time-series output of :func:`substructured_loop`.
TRACE_COLUMNS = (
    "t",
    "Fe",
    "y",
    "ydot",
    "command",
    "x",
    "xdot",
    "x_meas",
    "theta",
    "theta_true",
    "thetadot",
    "Fs",
    "Fs_true",
    "F_fb",
    "sync_error",
)
N_TRACE_COLUMNS = len(TRACE_COLUMNS)
N_HEAD = 12  # scalar slots before the histories
S_TICKS = 6
S_XPREV1 = 7
S_XPREV2 = 8
# x', x and theta' sin(theta) at the previous load-cell sample: P = (M2 + m) x'
# + C2 x + m l theta' sin(theta) is rebuilt from them with the current
# parameters, so a sweep of m, l, M2 or C2 does not kick the force.
S_P_XD = 9
S_P_X = 10
S_P_TH = 11
#: Periods in a row with dominant high-frequency content that flag instability.
HF_PERIODS = 2


@nb.njit(cache=True, nogil=True)
def state_offsets(n_cmd, n_pred, n_sections):
    """Offsets ``(cmd, cmd_dot, y_hist, f_hist, filter, length)`` in the state vector."""
    o_cmd = N_HEAD
    o_cmdd = o_cmd + n_cmd
    o_yh = o_cmdd + n_cmd
    o_fh = o_yh + n_pred
    o_z = o_fh + n_pred
    return o_cmd, o_cmdd, o_yh, o_fh, o_z, o_z + 2 * n_sections


@nb.njit(cache=True, nogil=True, inline="always")
def delayed_segment(r, tau, dt, off, n_cmd):
    """Command index and local time for delayed time ``t_k + r - tau``.

    Returns ``(j, sigma)``: the hold / Hermite segment starts at command
    ``c[j]`` (``off`` = 0 before this tick's command is pushed, 1 after) and
    ``sigma`` in [0, 1] is the position inside it.
    """
    q = (r - tau) / dt
    m = math.floor(q + 1e-9)
    if m > 0:
        m = 0
    j = off - m
    if j > n_cmd - 1:
        j = n_cmd - 1
    return j, q - m


@nb.njit(cache=True, nogil=True, inline="always")
def hermite(c0, d0, c1, d1, s, dt):
    """Cubic Hermite on one step: value, first and second time derivative."""
    s2 = s * s
    s3 = s2 * s
    v0 = dt * d0
    v1 = dt * d1
    x = (2 * s3 - 3 * s2 + 1) * c0 + (s3 - 2 * s2 + s) * v0 + (-2 * s3 + 3 * s2) * c1 + (s3 - s2) * v1
    xd = ((6 * s2 - 6 * s) * c0 + (3 * s2 - 4 * s + 1) * v0 + (-6 * s2 + 6 * s) * c1 + (3 * s2 - 2 * s) * v1) / dt
    xdd = ((12 * s - 6) * c0 + (6 * s - 4) * v0 + (-12 * s + 6) * c1 + (6 * s - 2) * v1) / (dt * dt)
    return x, xd, xdd


@nb.njit(cache=True, nogil=True, inline="always")
def pendulum_acc(th, thd, xdd, sgn, m, l, b1, b2, b3, g):
    fd = b1 * sgn + b2 * thd + b3 * thd * thd * sgn
    return -(fd + m * l * (g + xdd) * math.sin(th)) / (m * l * l)


@nb.njit(cache=True, nogil=True, inline="always")
def hermite_at(cmd, cmdd, j, s, dt):
    """Hermite segment from ``c[j]`` (older) to ``c[j - 1]`` (newer)."""
    return hermite(cmd[j], cmdd[j], cmd[j - 1], cmdd[j - 1], s, dt)


@nb.njit(cache=True, nogil=True, inline="always")
def quantise(value, step):
    """``value`` rounded to a multiple of ``step`` (unchanged when ``step`` is 0)."""
    return step * round(value / step) if step > 0.0 else value


@nb.njit(cache=True, nogil=True)
def trip(row, records, r_idx, ys, yds, th, thd, enc_res):
    """Fill the record rows from ``r_idx`` on with the period in which the loop tripped.

    The values are finite (the trip happens at the stroke limit at the latest):
    the running extremes of the interrupted period and the state at the trip.
    """
    th_x = quantise(th, enc_res)
    record_sample(row, ys, th_x)
    record_close(row, ys, yds, th_x, thd, 0)
    for r in range(max(r_idx, 0), records.shape[0]):
        records[r, :] = row


@nb.njit(cache=True, nogil=True)
def substructured_loop(
    state,
    p,
    M2,
    C2,
    alpha,
    fe,
    steps_per_period,
    substeps,
    actuator,
    tau,
    ws,
    zeta,
    n_cmd,
    w_pred,
    wd_pred,
    use_pred,
    sos,
    use_filter,
    w_force,
    use_force_pred,
    enc_res,
    lvdt_res,
    noise_f,
    noise_x,
    harmonics,
    stroke,
    hf_ratio,
    hf_accel,
    transient_periods,
    records,
    trace,
    stride,
):
    """Run the substructured loop for whole forcing periods.

    Parameters
    ----------
    state : float64[L]
        See the module docstring; overwritten with the final state.
    p : float64[10]
        ``ModelParams.kernel_array()``; ``M`` and ``C`` are the totals, the
        numerical model uses ``M1 = M - M2`` and ``C1 = C - C2``.
    M2, C2 : float
        Platform mass [kg] and damping [kg/s] (physical).
    alpha, fe : float
        Forcing amplitude [N] and frequency [Hz].
    steps_per_period, substeps : int
        Controller ticks per forcing period (``dt = 1/(fe n)``) and rig
        substeps per tick.
    actuator : int
        ``ACT_SERVO`` or ``ACT_HERMITE``.
    tau, ws, zeta : float
        Transport delay [s], servo natural frequency [rad/s] and damping ratio.
    n_cmd : int
        Length of the command delay line.
    w_pred, wd_pred : float64[N]
        Predictor weights for value and derivative on the ``y*`` history
        (most recent first); ``use_pred`` false sends ``y*`` itself.
    sos : float64[n_sections, 6]
        Band-pass second-order sections (``b0 b1 b2 a0 a1 a2``, ``a0 = 1``).
    w_force : float64[N]
        Predictor weights for the filtered force (``use_force_pred``).
    enc_res, lvdt_res : float
        Encoder [rad] and LVDT [m] quantisation steps (0: none).
    noise_f, noise_x : float64[n_ticks]
        Load-cell [N] and LVDT [m] noise, one value per tick.
    harmonics : float64[3]
        Load-cell vibration amplitudes [N] at 3, 5 and 7 times the forcing frequency.
    stroke : float
        Runaway limit on ``|x|`` and ``|y*|`` [m].
    hf_ratio, hf_accel : float
        High-frequency instability test, see the backend docs.
    transient_periods : int
        Periods run before the ``records`` rows (``records`` may have 0 rows).
    records : float64[n_rec, N_RECORD_COLUMNS]
        Per-period records of ``y*`` and the measured angle ``theta_x``.
    trace : float64[n_rows, N_TRACE_COLUMNS]
        Every ``stride``-th tick (0 rows: no trace); theta is not rewrapped
        when tracing.

    Returns
    -------
    status : int
        ``STATUS_OK``, ``STATUS_UNSTABLE`` or ``STATUS_DIVERGED``.
    periods_done : int
        Periods completed before the run stopped.
    """
    m = p[P_M_PEND]
    l = p[P_L]
    b1 = p[P_B1]
    b2 = p[P_B2]
    b3 = p[P_B3]
    g = p[P_G]
    M1 = p[P_M] - M2
    C1 = p[P_C] - C2
    K = p[P_K]
    k3 = p[P_K3]
    ms = M2 + m
    n = steps_per_period
    dt = 1.0 / (fe * n)
    h = dt / substeps
    we = TWO_PI * fe
    table = forcing_table(alpha, n)
    n_pred = w_pred.shape[0]
    n_sec = sos.shape[0]
    o_cmd, o_cmdd, o_yh, o_fh, o_z, _ = state_offsets(n_cmd, n_pred, n_sec)
    cmd = state[o_cmd:o_cmdd]
    cmdd = state[o_cmdd:o_yh]
    yh = state[o_yh:o_fh]
    fh = state[o_fh:o_z]
    z = state[o_z : o_z + 2 * n_sec]
    ys, yds, th, thd, x, xd = state[0], state[1], state[2], state[3], state[4], state[5]
    xp1, xp2 = state[S_XPREV1], state[S_XPREV2]
    mom_prev = ms * state[S_P_XD] + C2 * state[S_P_X] + m * l * state[S_P_TH]
    p_xd, p_x, p_th = state[S_P_XD], state[S_P_X], state[S_P_TH]
    servo = actuator == ACT_SERVO
    ws2 = ws * ws
    tzw = 2.0 * zeta * ws
    n_rec = records.shape[0]
    tracing = trace.shape[0] > 0
    total = transient_periods + n_rec
    hf_run = 0
    row = np.empty(N_RECORD_COLUMNS)  # the current period's running record
    status = STATUS_OK
    done = 0
    tick = 0
    for period in range(total):
        r_idx = period - transient_periods
        recording = r_idx >= 0
        record_open(row)
        sum_x2 = 0.0
        sum_h2 = 0.0
        for jstep in range(n):
            tk = jstep * dt
            # a. sensors. The load cell is read through an integrating ADC: the
            # sample is the mean of F_s over the last tick, which is exact as a
            # momentum difference because F_s = dP/dt (see the module docstring).
            p_xd, p_x, p_th = xd, x, thd * math.sin(th)
            mom = ms * p_xd + C2 * p_x + m * l * p_th
            fs_true = (mom - mom_prev) / dt
            mom_prev = mom
            ph = we * tk
            f_meas = (
                fs_true
                + noise_f[tick]
                + harmonics[0] * math.sin(3.0 * ph)
                + harmonics[1] * math.sin(5.0 * ph)
                + harmonics[2] * math.sin(7.0 * ph)
            )
            th_x = quantise(th, enc_res)
            x_meas = quantise(x, lvdt_res) + noise_x[tick]
            # b. force path
            f_fb = f_meas
            if use_filter:
                for sec in range(n_sec):
                    out = sos[sec, 0] * f_fb + z[2 * sec]
                    z[2 * sec] = sos[sec, 1] * f_fb - sos[sec, 4] * out + z[2 * sec + 1]
                    z[2 * sec + 1] = sos[sec, 2] * f_fb - sos[sec, 5] * out
                    f_fb = out
                if use_force_pred:
                    for i in range(n_pred - 1, 0, -1):
                        fh[i] = fh[i - 1]
                    fh[0] = f_fb
                    acc = 0.0
                    for i in range(n_pred):
                        acc += w_force[i] * fh[i]
                    f_fb = acc
            # outputs at t_k
            record_sample(row, ys, th_x)
            if tracing and (period * n + jstep) % stride == 0:
                ti = (period * n + jstep) // stride
                tr = trace[ti]
                tr[0] = (period * n + jstep) * dt
                tr[1] = table[2 * jstep]
                tr[2] = ys
                tr[3] = yds
                tr[4] = cmd[0]
                tr[5] = x
                tr[6] = xd
                tr[7] = x_meas
                tr[8] = th_x
                tr[9] = th
                tr[10] = thd
                tr[11] = f_meas
                tr[12] = fs_true
                tr[13] = f_fb
                tr[14] = ys - x_meas
            # c. numerical model, Eq. (3), force held over the step
            fe0 = table[2 * jstep] - f_fb
            feh = table[2 * jstep + 1] - f_fb
            fe1 = table[2 * jstep + 2] - f_fb
            k1y = yds
            k1v = (fe0 - C1 * yds - K * ys - k3 * ys * ys * ys) / M1
            y2 = ys + 0.5 * dt * k1y
            v2 = yds + 0.5 * dt * k1v
            k2y = v2
            k2v = (feh - C1 * v2 - K * y2 - k3 * y2 * y2 * y2) / M1
            y3 = ys + 0.5 * dt * k2y
            v3 = yds + 0.5 * dt * k2v
            k3y = v3
            k3v = (feh - C1 * v3 - K * y3 - k3 * y3 * y3 * y3) / M1
            y4 = ys + dt * k3y
            v4 = yds + dt * k3v
            k4y = v4
            k4v = (fe1 - C1 * v4 - K * y4 - k3 * y4 * y4 * y4) / M1
            ys = ys + dt / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y)
            yds = yds + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
            # d. command for t_k+1
            for i in range(n_pred - 1, 0, -1):
                yh[i] = yh[i - 1]
            yh[0] = ys
            for i in range(n_cmd - 1, 0, -1):
                cmd[i] = cmd[i - 1]
                cmdd[i] = cmdd[i - 1]
            if use_pred:
                c = 0.0
                cd = 0.0
                for i in range(n_pred):
                    c += w_pred[i] * yh[i]
                    cd += wd_pred[i] * yh[i]
                cmd[0] = c
                cmdd[0] = cd
            else:
                cmd[0] = ys
                cmdd[0] = yds
            # e. rig substeps over [t_k, t_k+1]
            for sub in range(substeps):
                r0 = sub * h
                sgn = signum(thd)
                if servo:
                    j, _s = delayed_segment(r0 + 0.5 * h, tau, dt, 1, n_cmd)
                    u = cmd[j]
                    a1 = ws2 * (u - x) - tzw * xd
                    q1 = pendulum_acc(th, thd, a1, sgn, m, l, b1, b2, b3, g)
                    x2 = x + 0.5 * h * xd
                    xd2 = xd + 0.5 * h * a1
                    th2 = th + 0.5 * h * thd
                    thd2 = thd + 0.5 * h * q1
                    a2 = ws2 * (u - x2) - tzw * xd2
                    q2 = pendulum_acc(th2, thd2, a2, sgn, m, l, b1, b2, b3, g)
                    x3 = x + 0.5 * h * xd2
                    xd3 = xd + 0.5 * h * a2
                    th3 = th + 0.5 * h * thd2
                    thd3 = thd + 0.5 * h * q2
                    a3 = ws2 * (u - x3) - tzw * xd3
                    q3 = pendulum_acc(th3, thd3, a3, sgn, m, l, b1, b2, b3, g)
                    x4 = x + h * xd3
                    xd4 = xd + h * a3
                    th4 = th + h * thd3
                    thd4 = thd + h * q3
                    a4 = ws2 * (u - x4) - tzw * xd4
                    q4 = pendulum_acc(th4, thd4, a4, sgn, m, l, b1, b2, b3, g)
                    x = x + h / 6.0 * (xd + 2.0 * xd2 + 2.0 * xd3 + xd4)
                    xd = xd + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
                else:
                    j, s = delayed_segment(r0 + 0.5 * h, tau, dt, 1, n_cmd)
                    s0 = s - 0.5 * h / dt  # segment time at the substep start
                    hs = h / dt
                    _x, _xd, a1 = hermite_at(cmd, cmdd, j, s0, dt)
                    _x, _xd, a2 = hermite_at(cmd, cmdd, j, s0 + 0.5 * hs, dt)
                    x, xd, a4 = hermite_at(cmd, cmdd, j, s0 + hs, dt)
                    q1 = pendulum_acc(th, thd, a1, sgn, m, l, b1, b2, b3, g)
                    th2 = th + 0.5 * h * thd
                    thd2 = thd + 0.5 * h * q1
                    q2 = pendulum_acc(th2, thd2, a2, sgn, m, l, b1, b2, b3, g)
                    th3 = th + 0.5 * h * thd2
                    thd3 = thd + 0.5 * h * q2
                    q3 = pendulum_acc(th3, thd3, a2, sgn, m, l, b1, b2, b3, g)
                    th4 = th + h * thd3
                    thd4 = thd + h * q3
                    q4 = pendulum_acc(th4, thd4, a4, sgn, m, l, b1, b2, b3, g)
                th = th + h / 6.0 * (thd + 2.0 * thd2 + 2.0 * thd3 + thd4)
                thd = thd + h / 6.0 * (q1 + 2.0 * q2 + 2.0 * q3 + q4)
            tick += 1
            # instability monitors: second difference of x at the controller rate
            d2 = x - 2.0 * xp1 + xp2
            xp2 = xp1
            xp1 = x
            sum_x2 += x * x
            sum_h2 += d2 * d2
            if not (abs(x) <= stroke and abs(ys) <= stroke):
                status = STATUS_UNSTABLE if math.isfinite(x) and math.isfinite(ys) else STATUS_DIVERGED
                break
        if status == STATUS_OK and not (math.isfinite(th) and math.isfinite(thd)):
            status = STATUS_DIVERGED
        if status == STATUS_UNSTABLE:
            trip(row, records, r_idx, ys, yds, th, thd, enc_res)
            break
        if status == STATUS_DIVERGED:
            for r in range(max(r_idx, 0), n_rec):
                for c_ in range(N_RECORD_COLUMNS):
                    records[r, c_] = np.nan
            break
        # high-frequency content: rms of x'' seen at the controller rate versus
        # what a pure forcing-frequency motion of the same rms would give
        hf = math.sqrt(sum_h2 / n) / (dt * dt)
        smooth = math.sqrt(sum_x2 / n) * we * we
        if hf > hf_accel and hf > hf_ratio * smooth:
            hf_run += 1
        else:
            hf_run = 0
        if hf_run >= HF_PERIODS:
            status = STATUS_UNSTABLE
            trip(row, records, r_idx, ys, yds, th, thd, enc_res)
            break
        turns = 0
        if not tracing:
            turns = wrap_index(th)
            th -= TWO_PI * turns
        if recording:
            th_x = quantise(th, enc_res)
            record_sample(row, ys, th_x)
            record_close(row, ys, yds, th_x, thd, turns)
            records[r_idx, :] = row
        done = period + 1
    state[0], state[1], state[2], state[3], state[4], state[5] = ys, yds, th, thd, x, xd
    state[S_TICKS] += tick
    state[S_XPREV1], state[S_XPREV2] = xp1, xp2
    state[S_P_XD], state[S_P_X], state[S_P_TH] = p_xd, p_x, p_th
    return status, done
