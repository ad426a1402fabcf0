"""The servo rig of the diagnosis testbench: platform, pendulum, load cell and controller conventions.

Written independently of :mod:`pendsweep.kernels` (no shared right-hand side or step): the
platform follows the delayed command through a first- or second-order servo, the pendulum rides
it, the load cell integrates the true interface force of Eq. (4) over each controller tick, and the
controller integrates Eq. (3) with its own conventions (RK4 or central difference, the command
ramped or held, an optional forward predictor). :func:`rig_truth` is the whole substructuring
test; :class:`Rig` describes one rig and controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from ...kernels._vector_width import WIDE_VECTORS  # noqa: F401  numba's CPU tuning as the kernels', whichever comes first

#: Valve of a first-order servo: its pole over the servo's corner frequency.
VALVE_RATIO = 5.0
#: Servo of the substructuring rig: transport delay [s], natural frequency [rad/s], damping ratio.
SERVO_DELAY, SERVO_WN, SERVO_ZETA = 0.003, 2.0 * math.pi * 40.0, 0.7


@nb.njit(cache=True, inline="always")
def _friction(thd, b1, b2, b3):
    """Pendulum friction torque of Eq. (2), sign taken at the stage itself."""
    s = 1.0 if thd > 0.0 else (-1.0 if thd < 0.0 else 0.0)
    return b1 * s + b2 * thd + b3 * thd * abs(thd)


@nb.njit(cache=True)
def _force(t, amps, freqs, sweep):
    """The external force at ``t`` [N]: tones ``amps[i] sin(2 pi freqs[i] t)`` and a linear sweep.

    ``sweep`` is ``(amplitude [N], f0 [Hz], f1 [Hz], duration [s])``: ``a sin(2 pi (f0 t + (f1 - f0)
    t^2 / (2 T)))`` for ``0 <= t <= T`` (the frequency rises from f0 to f1), none when the amplitude is 0.
    """
    f = 0.0
    for i in range(amps.shape[0]):
        f += amps[i] * math.sin(2.0 * math.pi * freqs[i] * t)
    if sweep[0] != 0.0 and t <= sweep[3]:
        f += sweep[0] * math.sin(2.0 * math.pi * (sweep[1] * t + 0.5 * (sweep[2] - sweep[1]) * t * t / sweep[3]))
    return f


@nb.njit(cache=True, inline="always")
def _rig_rhs(x, xd, th, thd, u, m, l, b, g, order, wn, zeta, servo_gain):
    """Servo platform and the pendulum on it: (x', x'', theta', theta'').

    ``order`` 2: ``x'' = wn^2 (g u - x) - 2 zeta wn x'``. Order 1: ``x' = wn (g u - x)``
    behind a valve :data:`VALVE_RATIO` times faster, ``x'' = r wn (wn (g u - x) - x')`` (a
    first-order servo whose velocity cannot jump: a real valve and oil column give the
    platform a finite acceleration, which the pendulum and the load cell feel).
    """
    if order == 2:
        xdd = wn * wn * (servo_gain * u - x) - 2.0 * zeta * wn * xd
    else:
        xdd = VALVE_RATIO * wn * (wn * (servo_gain * u - x) - xd)
    thdd = -(_friction(thd, b[0], b[1], b[2]) + m * l * (g + xdd) * math.sin(th)) / (m * l * l)
    return xd, xdd, thd, thdd


@nb.njit(cache=True, inline="always")
def _interface_force(xd, xdd, th, thd, thdd, M2, C2, m, l):
    """Eq. (4): force the platform and pendulum need from the actuator [N]."""
    return (M2 + m) * xdd + C2 * xd + m * l * (thdd * math.sin(th) + thd * thd * math.cos(th))


@nb.njit(cache=True, inline="always")
def _command_input(cmd, q, hold):
    """The actuator's command input at tick position ``q``: ramped linearly between ticks (hold 0) or held (1)."""
    if q <= 0.0:
        return cmd[0]
    j = int(math.floor(q))
    if hold == 1:
        return cmd[j]
    return cmd[j] + (q - j) * (cmd[j + 1] - cmd[j])


@nb.njit(cache=True)
def _rig_piece(x, xd, th, thd, t0, hp, cmd, delay, dt, hold, m, l, b, g, order, wn, zeta, servo_gain, M2, c2):
    """One RK4 step of the rig over ``[t0, t0 + hp]`` and the interface force's integral over it (trapezoid).

    A held command is constant over the piece (the caller splits steps at switches): its value at the
    piece's midpoint serves every stage.
    """
    if hold == 1:
        u1 = u2 = u4 = _command_input(cmd, (t0 + 0.5 * hp - delay) / dt, hold)
    else:
        u1 = _command_input(cmd, (t0 - delay) / dt, hold)
        u2 = _command_input(cmd, (t0 + 0.5 * hp - delay) / dt, hold)
        u4 = _command_input(cmd, (t0 + hp - delay) / dt, hold)
    dx1, dv1, dt1, dw1 = _rig_rhs(x, xd, th, thd, u1, m, l, b, g, order, wn, zeta, servo_gain)
    fa = _interface_force(xd, dv1, th, thd, dw1, M2, c2, m, l)
    dx2, dv2, dt2, dw2 = _rig_rhs(
        x + 0.5 * hp * dx1, xd + 0.5 * hp * dv1, th + 0.5 * hp * dt1, thd + 0.5 * hp * dw1,
        u2, m, l, b, g, order, wn, zeta, servo_gain,
    )  # fmt: skip
    dx3, dv3, dt3, dw3 = _rig_rhs(
        x + 0.5 * hp * dx2, xd + 0.5 * hp * dv2, th + 0.5 * hp * dt2, thd + 0.5 * hp * dw2,
        u2, m, l, b, g, order, wn, zeta, servo_gain,
    )  # fmt: skip
    dx4, dv4, dt4, dw4 = _rig_rhs(
        x + hp * dx3, xd + hp * dv3, th + hp * dt3, thd + hp * dw3, u4, m, l, b, g, order, wn, zeta, servo_gain
    )
    x += hp * (dx1 + 2.0 * dx2 + 2.0 * dx3 + dx4) / 6.0
    xd += hp * (dv1 + 2.0 * dv2 + 2.0 * dv3 + dv4) / 6.0
    th += hp * (dt1 + 2.0 * dt2 + 2.0 * dt3 + dt4) / 6.0
    thd += hp * (dw1 + 2.0 * dw2 + 2.0 * dw3 + dw4) / 6.0
    _, dvb, _, dwb = _rig_rhs(x, xd, th, thd, u4, m, l, b, g, order, wn, zeta, servo_gain)
    fb = _interface_force(xd, dvb, th, thd, dwb, M2, c2, m, l)
    return x, xd, th, thd, 0.5 * (fa + fb) * hp


@nb.njit(cache=True)
def rig_truth(
    z, m, l, b, g, M1, C1, K, k3, M2, C2, gain, gain_fs, amps, freqs, sweep, dt, nsub, n0, n,
    delay, order, wn, zeta, servo_gain, fs_noise, drift_c2, hold, predictor, load_cell_tau, integrator, point=0,
):  # fmt: skip
    """A substructuring test: controller at ``dt``, rig RK4 ``nsub`` steps per tick.

    Controller tick k: read the load cell (the interface force averaged over
    the last tick, through a first-order lag ``load_cell_tau`` [s] when > 0,
    times ``gain_fs``, plus ``fs_noise[k]``), one step of ``M1 y'' + C1 y' + K y
    + k3 y^3 = gain Fe(t) - Fs`` with Fs held (``integrator`` 0: RK4; 1: central
    difference), send the command: ``y*`` itself, or (``predictor`` not empty)
    ``sum_i predictor[i] y*[k - i]``, a forward prediction (:func:`predictor_weights`).
    The actuator's input is the command ramped over the next tick
    (``hold`` 0) or held (1); the platform follows it through a transport
    delay ``delay`` and a servo of ``order`` 1 or 2 (natural or corner
    frequency ``wn`` [rad/s], damping ratio ``zeta``, static gain ``servo_gain``).
    ``point`` 1: the load cell samples the interface force at the tick instead of averaging it
    (a held command's switch at the tick counts with its new value).

    Returns (n, 8): x [m], theta [rad], Fs measured [N], y_cmd [m], Fe [N], y* [m], and the platform's
    velocity x' [m/s] and acceleration x'' [m/s^2] at the tick (what a velocity sensor and an
    accelerometer sampled there read; a held command's switch at the tick counts with its new value).
    """
    out = np.empty((n, 8))
    ys, yds = 0.0, 0.0
    ys_prev = 0.0
    history = np.zeros(max(predictor.shape[0], 1))
    x, xd, th, thd = 0.0, 0.0, z[2], z[3]
    h = dt / nsub
    nt = n0 + n
    cmd = np.zeros(nt + 1)
    fs_meas = 0.0
    fs_lagged = 0.0
    total = max((n - 1) * dt, dt)
    for k in range(nt):
        t = k * dt
        c2 = C2 * (1.0 + drift_c2 * max(t - n0 * dt, 0.0) / total)
        if k >= n0:
            out[k - n0, 0], out[k - n0, 1], out[k - n0, 2] = x, th, fs_meas
            out[k - n0, 3], out[k - n0, 4], out[k - n0, 5] = cmd[k], _force(t, amps, freqs, sweep), ys
            u = _command_input(cmd, (t - delay) / dt, hold)
            out[k - n0, 6] = xd
            out[k - n0, 7] = _rig_rhs(x, xd, th, thd, u, m, l, b, g, order, wn, zeta, servo_gain)[1]
        if k == nt - 1:
            break
        # Controller: Eq. (3) over the tick with the measured force held.
        f0 = gain * _force(t, amps, freqs, sweep) - fs_meas
        fh = gain * _force(t + 0.5 * dt, amps, freqs, sweep) - fs_meas
        f1 = gain * _force(t + dt, amps, freqs, sweep) - fs_meas
        if integrator == 1:
            # Explicit central difference with the velocity centred (the classic hybrid-test integrator).
            if k == 0:
                ys_prev = ys - dt * yds + 0.5 * dt * dt * (f0 - C1 * yds - K * ys - k3 * ys**3) / M1
            lhs = M1 / (dt * dt) + C1 / (2.0 * dt)
            rhs = f0 - (K - 2.0 * M1 / (dt * dt)) * ys - (M1 / (dt * dt) - C1 / (2.0 * dt)) * ys_prev - k3 * ys**3
            ys_next = rhs / lhs
            yds = (ys_next - ys_prev) / (2.0 * dt)
            ys_prev, ys = ys, ys_next
        else:
            a1 = (f0 - C1 * yds - K * ys - k3 * ys**3) / M1
            p2, v2 = ys + 0.5 * dt * yds, yds + 0.5 * dt * a1
            a2 = (fh - C1 * v2 - K * p2 - k3 * p2**3) / M1
            p3, v3 = ys + 0.5 * dt * v2, yds + 0.5 * dt * a2
            a3 = (fh - C1 * v3 - K * p3 - k3 * p3**3) / M1
            p4, v4 = ys + dt * v3, yds + dt * a3
            a4 = (f1 - C1 * v4 - K * p4 - k3 * p4**3) / M1
            ys_next = ys + dt * (yds + 2.0 * v2 + 2.0 * v3 + v4) / 6.0
            yds = yds + dt * (a1 + 2.0 * a2 + 2.0 * a3 + a4) / 6.0
            ys = ys_next
        # Command: y*, or its forward prediction: weights over the last len(predictor) values of y*.
        for i in range(history.shape[0] - 1, 0, -1):
            history[i] = history[i - 1]
        history[0] = ys
        if predictor.shape[0] > 0:
            command = 0.0
            for i in range(predictor.shape[0]):
                command += predictor[i] * history[i]
        else:
            command = ys
        cmd[k + 1] = command
        # Rig over the tick; the load cell integrates the true interface force (trapezoid on the fine grid).
        # A held command switches at delay + i dt: a fine step across a switch is split there, so
        # that no RK4 step or trapezoid straddles the jump of the servo's acceleration.
        acc_f = 0.0
        for j in range(nsub):
            tj = t + j * h
            te = tj + h
            ts = te
            if hold == 1:
                ts = delay + (math.floor((tj - delay) / dt + 1e-9) + 1) * dt
                if not (tj + 1e-12 < ts < te - 1e-12):
                    ts = te
            x, xd, th, thd, f = _rig_piece(x, xd, th, thd, tj, ts - tj, cmd, delay, dt, hold, m, l, b, g,
                                           order, wn, zeta, servo_gain, M2, c2)  # fmt: skip
            acc_f += f
            if ts < te:
                x, xd, th, thd, f = _rig_piece(x, xd, th, thd, ts, te - ts, cmd, delay, dt, hold, m, l, b, g,
                                               order, wn, zeta, servo_gain, M2, c2)  # fmt: skip
                acc_f += f
        mean_force = acc_f / dt
        if point == 1:
            u = _command_input(cmd, (t + dt - delay) / dt, hold)
            _, xdd, _, thdd = _rig_rhs(x, xd, th, thd, u, m, l, b, g, order, wn, zeta, servo_gain)
            mean_force = _interface_force(xd, xdd, th, thd, thdd, M2, c2, m, l)
        if load_cell_tau > 0.0:
            fs_lagged += (mean_force - fs_lagged) * (1.0 - math.exp(-dt / load_cell_tau))
        else:
            fs_lagged = mean_force
        fs_meas = gain_fs * fs_lagged + fs_noise[k + 1]
    return out


def predictor_weights(lead: float, dt: float) -> np.ndarray:
    """Weights of a forward predictor: a least-squares quadratic through the last ``max(5, 10 ms / dt)``
    values of y*, evaluated ``lead`` seconds ahead (empty for no lead)."""
    if lead <= 0.0:
        return np.zeros(0)
    points = max(5, int(math.ceil(0.01 / dt)))
    times = -np.arange(points) * dt
    basis = np.stack([np.ones(points), times, times * times], axis=1)
    return np.array([1.0, lead, lead * lead]) @ np.linalg.pinv(basis)


@dataclass(frozen=True)
class Rig:
    """A substructuring rig and its controller's conventions (none of them the replay's own).

    Attributes
    ----------
    servo_order : int
        2: ``x'' = wn^2 (u - x) - 2 zeta wn x'``; 1: ``x' = wn (u - x)`` behind a fast valve.
    servo_hz : float
        Natural (order 2) or corner (order 1) frequency [Hz].
    servo_zeta : float
        Damping ratio (order 2).
    delay : float
        Transport delay before the servo [s].
    hold : int
        0: the actuator's input is the command ramped over a tick; 1: held (zero-order hold).
    lead : float
        Forward-predictor lead [s]: the command is y* extrapolated (:func:`predictor_weights`); 0: none.
    load_cell_tau : float
        First-order lag of the load cell after its tick average [s]; 0: none.
    integrator : int
        Controller's integrator: 0, RK4 with the force held; 1, explicit central difference.
    calibration_error : float
        The lab's nominal delay differs from the true effective delay by this much [s] (a calibration's error).
    describes_servo : bool
        The record's metadata describes the servo (actuator table); otherwise only its delay ``tau``.
    point_load_cell : bool
        The load cell samples the interface force at the tick instead of averaging it over the tick.
    declares_daq : bool
        The record's metadata declares the load cell's sampling and the command's hold (``daq``), and
        its nominal delay leaves out the half tick a held command adds (the replay models the hold).
    """

    servo_order: int = 2
    servo_hz: float = SERVO_WN / (2.0 * math.pi)
    servo_zeta: float = SERVO_ZETA
    delay: float = SERVO_DELAY
    hold: int = 0
    lead: float = 0.0
    load_cell_tau: float = 0.0
    integrator: int = 0
    calibration_error: float = 0.0
    describes_servo: bool = False
    point_load_cell: bool = False
    declares_daq: bool = False

    @property
    def wn(self) -> float:
        return 2.0 * math.pi * self.servo_hz

    def servo_lag(self, wn: float | None = None) -> float:
        """The servo's low-frequency group delay [s]."""
        wn = self.wn if wn is None else wn
        return 2.0 * self.servo_zeta / wn if self.servo_order == 2 else 1.0 / wn

    def effective_delay(self, dt: float) -> float:
        """The rig's low-frequency delay from command to platform [s] (a held command adds half a tick)."""
        return self.delay + self.servo_lag() + (0.5 * dt if self.hold else 0.0)
