"""The rig's half of a substructured tick, for an experimental site that a controller drives over a socket.

The in-process loop (:mod:`._substructured`) runs controller and rig in one
kernel; a site (:mod:`pendsweep.hybrid`) receives the controller's command
instead and runs only the rig's steps, with the same functions: the command
enters the delay line, :func:`~._substructured.rig_advance` moves the rig over
one step, :func:`~._substructured.sense` reads its sensors.
"""

import numba as nb

from ._actuator import push
from ._layout import model_params, pendulum_params
from ._substructured import (
    S_THETA,
    S_THETADOT,
    S_TICKS,
    S_X,
    S_XDOT,
    command_tick,
    rig_advance,
    sense,
    state_offsets,
)

#: Slots of the readings vector written by :func:`rig_trial` and :func:`rig_reading`.
READING_NAMES = ("Fs", "Fs_true", "theta", "x_meas", "x", "xdot", "theta_true", "thetadot", "xddot_mean")
N_READINGS = len(READING_NAMES)


@nb.njit(cache=True, nogil=True, inline="always")
def _store(out, readings, s, xddot_mean):
    f_meas, fs_true, th_x, x_meas = readings
    out[0], out[1], out[2], out[3] = f_meas, fs_true, th_x, x_meas
    out[4], out[5], out[6], out[7] = s[S_X], s[S_XDOT], s[S_THETA], s[S_THETADOT]
    out[8] = xddot_mean


@nb.njit(cache=True, nogil=True)
def rig_reading(s, p, cfg, dt, noise_f, noise_x, phase, out):
    """The sensors of rig state ``s`` without moving it (a reading before the first trial).

    ``p`` is ``ModelParams.kernel_array()``; ``out`` receives :data:`READING_NAMES`.
    """
    m, l = pendulum_params(p)[:2]
    _store(out, sense(s, m + cfg.M2, cfg, m, l, dt, noise_f, noise_x, phase), s, 0.0)


@nb.njit(cache=True, nogil=True)
def rig_trial(s, command, slope, p, pend, cfg, dt, noise_f, noise_x, phase, out):
    """Move rig state ``s`` one step of ``dt`` [s] towards ``command`` [m] (with ``slope`` [m/s]).

    The command and its slope enter the delay line, the actuator and
    pendulum are integrated over the step and the sensors read at its end,
    exactly as steps d-e and a of the in-process tick. ``pend`` is
    ``(m, l, b1, b2, b3, g)``; ``out`` receives :data:`READING_NAMES`,
    ``xddot_mean`` being the platform's mean acceleration over the step [m/s^2].
    """
    o_cmd, o_cmdd, o_yh, _o_fh, _o_z, _end = state_offsets(cfg.n_cmd, cfg.w_pred.shape[0], cfg.sos.shape[0])
    cmd = s[o_cmd:o_cmdd]
    cmdd = s[o_cmdd:o_yh]
    push(cmd, command)
    push(cmdd, slope)
    xd0 = s[S_XDOT]
    rig_advance(s, cmd, cmdd, cfg, pend, dt)
    m, l = pend[0], pend[1]
    readings = sense(s, m + cfg.M2, cfg, m, l, dt, noise_f, noise_x, phase)
    s[S_TICKS] += 1.0
    _store(out, readings, s, (s[S_XDOT] - xd0) / dt)


@nb.njit(cache=True, nogil=True)
def client_tick(s, p, cfg, table, jstep, k, readings, row, tr):
    """The controller's half of tick ``k`` (steps b-d) for a rig on the far side of a socket.

    ``readings = (f_meas, fs_true, theta_x, x_meas)`` are the site's at the
    tick's start (``fs_true`` NaN when not measured), with ``s``'s x, x',
    theta, theta' set from them; ``table`` is
    :func:`~._emulated.forcing_table` of the forcing. Returns the command for
    the next tick and its slope ``(c [m], c' [m/s])``.
    """
    o_cmd, o_cmdd, o_yh, o_fh, o_z, end = state_offsets(cfg.n_cmd, cfg.w_pred.shape[0], cfg.sos.shape[0])
    hist = (s[o_cmd:o_cmdd], s[o_cmdd:o_yh], s[o_yh:o_fh], s[o_fh:o_z], s[o_z:end])
    model = model_params(p, cfg.M2, cfg.C2)
    dt = 1.0 / (cfg.fe * cfg.steps_per_period)
    command_tick(
        s, hist, jstep, k, dt, table, model, cfg, (readings[0], readings[1], readings[2], readings[3]), row, tr
    )
    return hist[0][0], hist[1][0]
