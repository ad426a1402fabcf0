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
   (signum of ``th'`` held over a substep). The servo's held command
   switches, and the Hermite interpolant's ``x''`` jumps, where the delayed
   time crosses a tick; a substep holding that instant is split there, so
   the rig depends continuously on ``tau`` (smoothly between the sampling
   instants).

State vector (float64, see :func:`state_offsets`): ``0 y*, 1 y*', 2 theta,
3 theta' (true), 4 x, 5 x', 6 ticks done since the initial state, 7-8 x at
the two previous ticks, 9-11 x', x and theta' sin(theta) at the previous
load-cell sample``, then the command delay line ``c`` (most recent
first), the command derivatives, the ``y*`` history, the filtered-force
history and the filter's ``2 n_sections`` delay registers.
"""

import math
from typing import NamedTuple

import numba as nb
import numpy as np

from ._actuator import ACT_SERVO, delayed_segment, hermite_at, push, weighted_sum
from ._emulated import forcing_table
from ._layout import (
    N_RECORD_COLUMNS,
    STATUS_DIVERGED,
    STATUS_OK,
    STATUS_UNSTABLE,
    model_params,
    pendulum_params,
)
from ._records import TWO_PI, record_close, record_open, record_sample, wrap_index
from ._rhs import signum
from ._steps import model_rk4, pivot_pendulum_rk4, servo_rig_rk4

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
# Slots of the state vector (the histories follow, see state_offsets).
S_Y, S_YDOT, S_THETA, S_THETADOT, S_X, S_XDOT = range(6)
S_TICKS = 6
S_XPREV1 = 7
S_XPREV2 = 8
# x', x and theta' sin(theta) at the previous load-cell sample: P = (M2 + m) x'
# + C2 x + m l theta' sin(theta) is rebuilt from them with the current
# parameters, so a sweep of m, l, M2 or C2 does not kick the force.
S_P_XD = 9
S_P_X = 10
S_P_TH = 11
N_HEAD = 12  # scalar slots before the histories
#: Periods in a row with dominant high-frequency content that flag instability.
HF_PERIODS = 2


class LoopSettings(NamedTuple):
    """Everything the loop needs besides its state, parameters, noise and outputs.

    Attributes
    ----------
    M2, C2 : float
        Platform mass [kg] and damping [kg/s] (physical).
    alpha, fe : float
        Forcing amplitude [N] and frequency [Hz].
    steps_per_period, substeps : int
        Controller ticks per forcing period (``dt = 1/(fe n)``) and rig substeps per tick.
    actuator : int
        ``ACT_SERVO`` or ``ACT_HERMITE`` (:mod:`pendsweep.kernels._actuator`).
    tau, ws, zeta : float
        Transport delay [s], servo natural frequency [rad/s] and damping ratio.
    n_cmd : int
        Length of the command delay line.
    use_pred : bool
        Predict the command; otherwise ``y*`` itself is sent.
    w_pred, wd_pred : float64[N]
        Predictor weights for value and slope on the ``y*`` history (most recent first).
    use_filter : bool
        Band-pass the measured force with ``sos``.
    sos : float64[n_sections, 6]
        Second-order sections (``b0 b1 b2 a0 a1 a2``, ``a0 = 1``).
    use_force_pred : bool
        Predict the filtered force forward with ``w_force`` (float64[N]).
    enc_res, lvdt_res : float
        Encoder [rad] and LVDT [m] quantisation steps (0: none).
    harmonics : float64[3]
        Load-cell vibration amplitudes [N] at 3, 5 and 7 times the forcing frequency.
    stroke : float
        Runaway limit on ``|x|`` and ``|y*|`` [m].
    hf_ratio, hf_accel : float
        High-frequency instability test, see the backend docs.
    sign_eps : float
        0: the signum of theta' in the pendulum damping is held over each rig
        substep (non-smooth, as a rig's friction is); ``> 0``: ``tanh(theta' /
        sign_eps)`` [rad/s] at each substep's start, a smooth tick map for
        continuation (:mod:`pendsweep.analysis.continuation.loop`).
    """

    M2: float
    C2: float
    alpha: float
    fe: float
    steps_per_period: int
    substeps: int
    actuator: int
    tau: float
    ws: float
    zeta: float
    n_cmd: int
    use_pred: bool
    w_pred: np.ndarray
    wd_pred: np.ndarray
    use_filter: bool
    sos: np.ndarray
    use_force_pred: bool
    w_force: np.ndarray
    enc_res: float
    lvdt_res: float
    harmonics: np.ndarray
    stroke: float
    hf_ratio: float
    hf_accel: float
    sign_eps: float


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
def quantise(value, step):
    """``value`` rounded to a multiple of ``step`` (unchanged when ``step`` is 0)."""
    return step * round(value / step) if step > 0.0 else value


@nb.njit(cache=True, nogil=True, inline="always")
def interface_momentum(xd, x, thd_sin_th, ms, C2, m, l):
    """``P = m_s x' + C2 x + m l theta' sin(theta)``, whose rate is the interface force Eq. (4) [N s]."""
    return ms * xd + C2 * x + m * l * thd_sin_th


@nb.njit(cache=True, nogil=True, inline="always")
def load_cell(fs_true, noise, harmonics, phase):
    """Measured force: the true tick-mean force plus white noise and odd servo harmonics [N]."""
    return (
        fs_true
        + noise
        + harmonics[0] * math.sin(3.0 * phase)
        + harmonics[1] * math.sin(5.0 * phase)
        + harmonics[2] * math.sin(7.0 * phase)
    )


@nb.njit(cache=True, nogil=True, inline="always")
def force_path(f_meas, cfg, z, fh):
    """The fed-back force: optional band-pass (DF-II transposed), then optional forward prediction."""
    f_fb = f_meas
    if cfg.use_filter:
        sos = cfg.sos
        for sec in range(sos.shape[0]):
            out = sos[sec, 0] * f_fb + z[2 * sec]
            z[2 * sec] = sos[sec, 1] * f_fb - sos[sec, 4] * out + z[2 * sec + 1]
            z[2 * sec + 1] = sos[sec, 2] * f_fb - sos[sec, 5] * out
            f_fb = out
        if cfg.use_force_pred:
            push(fh, f_fb)
            f_fb = weighted_sum(cfg.w_force, fh)
    return f_fb


@nb.njit(cache=True, nogil=True, inline="always")
def next_command(ys, yds, cfg, yh, cmd, cmdd):
    """Push the command for the next tick: ``y*`` predicted by ``tau_hat``, or ``y*`` itself."""
    push(yh, ys)
    if cfg.use_pred:
        push(cmd, weighted_sum(cfg.w_pred, yh))
        push(cmdd, weighted_sum(cfg.wd_pred, yh))
    else:
        push(cmd, ys)
        push(cmdd, yds)


@nb.njit(cache=True, nogil=True, inline="always")
def rig_tick(x, xd, th, thd, cmd, cmdd, cfg, pend, dt):
    """The rig over one controller tick in ``cfg.substeps`` RK4 substeps.

    The delayed command crosses from one command sample to the next (the
    servo's held value switches, the Hermite interpolant's ``x''`` jumps) at
    the same instant of every tick, ``tau`` modulo ``dt``: it is found once
    per tick, and the substep holding it is split there, so every RK4 stage
    sees one piece and the rig depends continuously on ``tau``. The signum of
    theta' is held over a substep. ``pend = (m, l, b1, b2, b3, g)``.
    """
    h = dt / cfg.substeps
    ws2 = cfg.ws * cfg.ws
    tzw = 2.0 * cfg.zeta * cfg.ws
    j, s = delayed_segment(0.0, cfg.tau, dt, 1, cfg.n_cmd)  # the piece at the tick's start
    knot = (1.0 - s) * dt  # where it ends (dt or beyond: not inside this tick)
    edge = 1e-9 * dt
    for sub in range(cfg.substeps):
        r0 = sub * h
        sgn = signum(thd) if cfg.sign_eps == 0.0 else math.tanh(thd / cfg.sign_eps)
        p_servo = (ws2, tzw, sgn) + pend
        p_pend = (sgn,) + pend
        # the substep's first piece (sample j before the knot, j - 1 after it) and what is left past the knot
        if r0 + h <= knot + edge:
            first, s0, length, rest = j, s + r0 / dt, h, 0.0
        elif r0 >= knot - edge:
            first, s0, length, rest = j - 1, s + r0 / dt - 1.0, h, 0.0
        else:
            first, s0, length, rest = j, s + r0 / dt, knot - r0, r0 + h - knot
        x, xd, th, thd = rig_piece(x, xd, th, thd, first, s0, length, cmd, cmdd, cfg, p_servo, p_pend, dt)
        if rest > 0.0:
            x, xd, th, thd = rig_piece(x, xd, th, thd, j - 1, 0.0, rest, cmd, cmdd, cfg, p_servo, p_pend, dt)
    return x, xd, th, thd


@nb.njit(cache=True, nogil=True, inline="always")
def rig_piece(x, xd, th, thd, j, s, length, cmd, cmdd, cfg, p_servo, p_pend, dt):
    """The rig over ``length`` [s] on one piece of the delayed command: sample ``j`` held (servo), or the
    Hermite segment from sample ``j`` entered at position ``s`` (delay and ideal actuators)."""
    if cfg.actuator == ACT_SERVO:
        u = cmd[j]
        return servo_rig_rk4((x, xd, th, thd), u, u, u, length, p_servo)
    return hermite_rk4(th, thd, cmd, cmdd, j, s, length, dt, p_pend)


@nb.njit(cache=True, nogil=True, inline="always")
def hermite_rk4(th, thd, cmd, cmdd, j, s, h, dt, p_pend):
    """The pendulum over ``h`` [s] on Hermite segment ``j`` from position ``s`` in it; ``(x, x', th, th')`` at the end."""
    hs = h / dt
    _x, _xd, a1 = hermite_at(cmd, cmdd, j, s, dt)
    _x, _xd, a2 = hermite_at(cmd, cmdd, j, s + 0.5 * hs, dt)
    x, xd, a4 = hermite_at(cmd, cmdd, j, s + hs, dt)
    th, thd = pivot_pendulum_rk4((th, thd), a1, a2, a4, h, p_pend)
    return x, xd, th, thd


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


@nb.njit(cache=True, nogil=True, inline="always")
def write_trace(tr, t, fe_t, ys, yds, command, x, xd, x_meas, th_x, th, thd, f_meas, fs_true, f_fb):
    """One row of :data:`TRACE_COLUMNS`."""
    tr[0] = t
    tr[1] = fe_t
    tr[2] = ys
    tr[3] = yds
    tr[4] = command
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


@nb.njit(cache=True, nogil=True, inline="always")
def high_frequency_growth(sum_x2, sum_h2, n, dt, we, cfg):
    """Whether the period's rms x'' at the controller rate is dominated by high frequencies.

    Compares the rms second difference of ``x`` with what a pure
    forcing-frequency motion of the same rms would give.
    """
    hf = math.sqrt(sum_h2 / n) / (dt * dt)
    smooth = math.sqrt(sum_x2 / n) * we * we
    return hf > cfg.hf_accel and hf > cfg.hf_ratio * smooth


@nb.njit(cache=True, nogil=True, inline="always")
def sense(s, ms, cfg, m, l, dt, noise_f, noise_x, phase):
    """Step a, the rig's sensors at the current tick, on the state vector ``s``.

    The load cell is read through an integrating ADC: the sample is the mean
    of F_s over the last tick, exact as a momentum difference because
    F_s = dP/dt (see the module docstring). The momentum slots of ``s`` move
    on to this tick. ``phase`` is the forcing phase of the odd harmonics.

    Returns
    -------
    (f_meas [N], fs_true [N], theta_x [rad], x_meas [m])
    """
    x, xd, th, thd = s[S_X], s[S_XDOT], s[S_THETA], s[S_THETADOT]
    mom_prev = interface_momentum(s[S_P_XD], s[S_P_X], s[S_P_TH], ms, cfg.C2, m, l)
    s[S_P_XD], s[S_P_X], s[S_P_TH] = xd, x, thd * math.sin(th)
    fs_true = (interface_momentum(s[S_P_XD], s[S_P_X], s[S_P_TH], ms, cfg.C2, m, l) - mom_prev) / dt
    f_meas = load_cell(fs_true, noise_f, cfg.harmonics, phase)
    return f_meas, fs_true, quantise(th, cfg.enc_res), quantise(x, cfg.lvdt_res) + noise_x


@nb.njit(cache=True, nogil=True, inline="always")
def command_tick(s, hist, jstep, k, dt, table, model, cfg, readings, row, tr):
    """Steps b-d, the controller's part of a tick, given the sensor ``readings`` of :func:`sense`.

    Feeds the force back, samples the record row and the trace row ``tr``
    (length 0: none; x, x', theta, theta' are read from ``s``), integrates
    the numerical model over the tick and pushes the next command into the
    delay line of ``hist = (cmd, cmdd, y_hist, f_hist, filter registers)``.
    """
    cmd, cmdd, yh, fh, z = hist
    f_meas, fs_true, th_x, x_meas = readings
    ys, yds = s[S_Y], s[S_YDOT]
    f_fb = force_path(f_meas, cfg, z, fh)
    record_sample(row, ys, th_x)
    if tr.shape[0] > 0:
        write_trace(tr, k * dt, table[2 * jstep], ys, yds, cmd[0], s[S_X], s[S_XDOT], x_meas, th_x, s[S_THETA],
                    s[S_THETADOT], f_meas, fs_true, f_fb)  # fmt: skip
    # c. numerical model, Eq. (3), force held over the step
    ys, yds = model_rk4(
        (ys, yds), table[2 * jstep] - f_fb, table[2 * jstep + 1] - f_fb, table[2 * jstep + 2] - f_fb, dt, model
    )
    # d. command for t_k+1
    next_command(ys, yds, cfg, yh, cmd, cmdd)
    s[S_Y], s[S_YDOT] = ys, yds


@nb.njit(cache=True, nogil=True, inline="always")
def rig_advance(s, cmd, cmdd, cfg, pend, dt):
    """Step e, the rig over one tick driven by the command delay line ``cmd``, ``cmdd``, on ``s``."""
    x, xd, th, thd = rig_tick(s[S_X], s[S_XDOT], s[S_THETA], s[S_THETADOT], cmd, cmdd, cfg, pend, dt)
    s[S_X], s[S_XDOT], s[S_THETA], s[S_THETADOT] = x, xd, th, thd


@nb.njit(cache=True, nogil=True, inline="always")
def controller_tick(s, hist, jstep, k, tick, dt, we, table, model, pend, ms, cfg, noise_f, noise_x, row, tr):
    """One controller tick, steps a-e of the module docstring, on the state vector ``s``.

    The rig's part (:func:`sense`, :func:`rig_advance`) and the controller's
    (:func:`command_tick`) are separate functions because an experimental
    site (:mod:`pendsweep.hybrid`) runs the rig's part on the far side of a socket.
    """
    readings = sense(s, ms, cfg, pend[0], pend[1], dt, noise_f[tick], noise_x[tick], we * (jstep * dt))
    command_tick(s, hist, jstep, k, dt, table, model, cfg, readings, row, tr)
    rig_advance(s, hist[0], hist[1], cfg, pend, dt)


@nb.njit(cache=True, nogil=True, inline="always")
def stroke_status(x, ys, stroke):
    """``STATUS_OK`` while ``|x|`` and ``|y*|`` are within the stroke [m]; past it, unstable (finite) or diverged."""
    if abs(x) <= stroke and abs(ys) <= stroke:
        return STATUS_OK
    return STATUS_UNSTABLE if math.isfinite(x) and math.isfinite(ys) else STATUS_DIVERGED


@nb.njit(cache=True, nogil=True, inline="always")
def close_period(s, row, records, r_idx, status, hf_run, tracing, cfg):
    """Period-end bookkeeping: divergence, trips, rewrapping and the record row.

    Returns the final ``(status, hf_run)``; a status other than OK ends the run.
    """
    ys, yds, th, thd = s[S_Y], s[S_YDOT], s[S_THETA], s[S_THETADOT]
    if status == STATUS_OK and not (math.isfinite(th) and math.isfinite(thd)):
        status = STATUS_DIVERGED
    if status == STATUS_DIVERGED:
        for r in range(max(r_idx, 0), records.shape[0]):
            records[r, :] = np.nan
        return status, hf_run
    if status == STATUS_OK and hf_run >= HF_PERIODS:
        status = STATUS_UNSTABLE
    if status == STATUS_UNSTABLE:
        trip(row, records, r_idx, ys, yds, th, thd, cfg.enc_res)
        return status, hf_run
    turns = 0
    if not tracing:
        turns = wrap_index(th)
        th -= TWO_PI * turns
        s[S_THETA] = th
    if r_idx >= 0:
        th_x = quantise(th, cfg.enc_res)
        record_sample(row, ys, th_x)
        record_close(row, ys, yds, th_x, thd, turns)
        records[r_idx, :] = row
    return status, hf_run


@nb.njit(cache=True, nogil=True)
def substructured_loop(state, p, cfg, noise_f, noise_x, transient_periods, records, trace, stride):
    """Run the substructured loop for whole forcing periods.

    Parameters
    ----------
    state : float64[L]
        See the module docstring and :func:`state_offsets`; overwritten with the final state.
    p : float64[N_PARAMS]
        ``ModelParams.kernel_array()``; ``M`` and ``C`` are the totals, the
        numerical model uses ``M1 = M - M2`` and ``C1 = C - C2``.
    cfg : LoopSettings
        Loop options (actuator, predictor, filter, sensors, monitors).
    noise_f, noise_x : float64[n_ticks]
        Load-cell [N] and LVDT [m] noise, one value per tick.
    transient_periods : int
        Periods run before the ``records`` rows (``records`` may have 0 rows).
    records : float64[n_rec, N_RECORD_COLUMNS]
        Per-period records of ``y*`` and the measured angle ``theta_x``.
    trace : float64[n_rows, N_TRACE_COLUMNS]
        Every ``stride``-th tick (0 rows: no trace); theta is not rewrapped when tracing.

    Returns
    -------
    status : int
        ``STATUS_OK``, ``STATUS_UNSTABLE`` or ``STATUS_DIVERGED``.
    periods_done : int
        Periods completed before the run stopped.
    """
    pend = pendulum_params(p)
    model = model_params(p, cfg.M2, cfg.C2)
    n = cfg.steps_per_period
    dt = 1.0 / (cfg.fe * n)
    we = TWO_PI * cfg.fe
    table = forcing_table(cfg.alpha, n)
    o_cmd, o_cmdd, o_yh, o_fh, o_z, end = state_offsets(cfg.n_cmd, cfg.w_pred.shape[0], cfg.sos.shape[0])
    hist = (state[o_cmd:o_cmdd], state[o_cmdd:o_yh], state[o_yh:o_fh], state[o_fh:o_z], state[o_z:end])
    no_row = np.empty(0)
    tracing = trace.shape[0] > 0
    row = np.empty(N_RECORD_COLUMNS)  # the current period's running record
    status, hf_run, done, tick = STATUS_OK, 0, 0, 0
    for period in range(transient_periods + records.shape[0]):
        record_open(row)
        sum_x2 = 0.0
        sum_h2 = 0.0
        for jstep in range(n):
            k = period * n + jstep
            tr = trace[k // stride] if tracing and k % stride == 0 else no_row
            controller_tick(state, hist, jstep, k, tick, dt, we, table, model, pend, pend[0] + cfg.M2, cfg,
                            noise_f, noise_x, row, tr)  # fmt: skip
            tick += 1
            # instability monitors: second difference of x at the controller rate
            x = state[S_X]
            d2 = x - 2.0 * state[S_XPREV1] + state[S_XPREV2]
            state[S_XPREV2], state[S_XPREV1] = state[S_XPREV1], x
            sum_x2 += x * x
            sum_h2 += d2 * d2
            status = stroke_status(x, state[S_Y], cfg.stroke)
            if status != STATUS_OK:
                break
        if status == STATUS_OK:
            hf_run = hf_run + 1 if high_frequency_growth(sum_x2, sum_h2, n, dt, we, cfg) else 0
        status, hf_run = close_period(state, row, records, period - transient_periods, status, hf_run, tracing, cfg)
        if status != STATUS_OK:
            break
        done = period + 1
    state[S_TICKS] += tick
    return status, done
