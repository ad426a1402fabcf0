"""Per-step bookkeeping of the per-period records, shared by all kernels."""

import math

import numba as nb
import numpy as np

from ._layout import (
    REC_ROTATIONS,
    REC_THETA_ABSMAX,
    REC_THETA_PEAK,
    REC_THETA_SEC,
    REC_THETADOT_SEC,
    REC_Y_ABSMAX,
    REC_Y_SEC,
    REC_YDOT_SEC,
)

TWO_PI = 2.0 * math.pi


@nb.njit(cache=True, nogil=True, inline="always")
def wrap_index(theta):
    """Integer k with theta - 2 pi k in (-pi, pi]."""
    return math.ceil((theta - math.pi) / TWO_PI)


@nb.njit(cache=True, nogil=True, inline="always")
def wrap_turns(theta):
    """:func:`wrap_index` as a float, for the angle arithmetic of vectorised loops.

    A float-to-integer conversion has no packed form on AVX2 (AVX-512 has
    one), so ``wrap_index`` made LLVM leave the batched lane loop for scalar
    conversions lane by lane. ``np.ceil`` stays a packed rounding; adding
    ``+0.0`` turns its ``-0.0`` (for theta in (-pi, pi]) into the ``+0.0``
    the integer gave, so ``theta - 2 pi k`` keeps its bits even at
    ``theta = -0.0``. The same
    value as ``float(wrap_index(theta))`` wherever that integer exists
    (``|theta| < 2**63 * 2 pi``).
    """
    return np.ceil((theta - math.pi) / TWO_PI) + 0.0


@nb.njit(cache=True, nogil=True, inline="always")
def wrap_angle(theta):
    """theta wrapped to (-pi, pi]."""
    return theta - TWO_PI * wrap_turns(theta)


@nb.njit(cache=True, nogil=True, inline="always")
def record_open(row):
    for j in range(row.shape[0]):
        row[j] = 0.0


@nb.njit(cache=True, nogil=True, inline="always")
def fold_extremes(theta_absmax, theta_peak, y_absmax, y, theta):
    """Running extremes of a period updated with one sample (branch-free, vectorisable).

    Returns the new ``(theta_absmax, theta_peak, y_absmax)``.
    """
    w = wrap_angle(theta)
    aw = abs(w)
    larger = aw > theta_absmax
    ay = abs(y)
    return (aw if larger else theta_absmax), (w if larger else theta_peak), (ay if ay > y_absmax else y_absmax)


@nb.njit(cache=True, nogil=True, inline="always")
def record_sample(row, y, theta):
    """Fold one sample into the running extremes of the current period."""
    row[REC_THETA_ABSMAX], row[REC_THETA_PEAK], row[REC_Y_ABSMAX] = fold_extremes(
        row[REC_THETA_ABSMAX], row[REC_THETA_PEAK], row[REC_Y_ABSMAX], y, theta
    )


@nb.njit(cache=True, nogil=True, inline="always")
def record_close(row, y, ydot, theta, thetadot, turns):
    row[REC_Y_SEC] = y
    row[REC_YDOT_SEC] = ydot
    row[REC_THETA_SEC] = wrap_angle(theta)
    row[REC_THETADOT_SEC] = thetadot
    row[REC_ROTATIONS] = turns
