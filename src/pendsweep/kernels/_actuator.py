"""The transfer system inside the kernels: the command delay line and the actuator models.

The controller pushes one command sample (value and slope) per tick into a
delay line (most recent first). The actuator sees it ``tau`` later:

* servo (:data:`ACT_SERVO`): a zero-order hold of the delayed samples drives
  ``x'' = ws^2 (u - x) - 2 zeta ws x'`` (:func:`~pendsweep.kernels._rhs.servo_rig_rhs`);
* delay / ideal (:data:`ACT_HERMITE`): ``x(t) = c(t - tau)``, the cubic
  Hermite interpolant of the samples and their slopes, so ``x`` and ``x'`` are
  continuous and ``x''`` is piecewise linear (``tau = 0``: the ideal actuator).
"""

import math

import numba as nb

ACT_SERVO = 0
ACT_HERMITE = 1


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
def hermite_at(cmd, cmdd, j, s, dt):
    """Hermite segment from ``c[j]`` (older) to ``c[j - 1]`` (newer)."""
    return hermite(cmd[j], cmdd[j], cmd[j - 1], cmdd[j - 1], s, dt)


@nb.njit(cache=True, nogil=True, inline="always")
def push(line, value):
    """Shift a history (most recent first) by one and store ``value`` at its head."""
    for i in range(line.shape[0] - 1, 0, -1):
        line[i] = line[i - 1]
    line[0] = value


@nb.njit(cache=True, nogil=True, inline="always")
def weighted_sum(weights, history):
    """``weights @ history`` (a polynomial predictor applied to a history)."""
    acc = 0.0
    for i in range(history.shape[0]):
        acc += weights[i] * history[i]
    return acc
