"""The exact step of a servo model driven by a cubic input: the transfer models' discretisation.

The servo models of :mod:`.transfer` are linear and their input is a cubic over each step (the
command's Hermite interpolant, or a piece of a held or ramped command), so one step is exact as
the matrix exponential of the system augmented with the input's derivatives; the kernels
(:func:`pendsweep.kernels._measured.transfer_trace`, ``sampled_transfer_trace``) apply it.
"""

from __future__ import annotations

import math

import numpy as np


def servo_propagator(order: int, rate: float, zeta: float, h: float) -> np.ndarray:
    """The exact step ``h`` of a servo whose input is a cubic over the step: a 2 x 6 matrix on
    ``(x, x', u, u', u'', u''')``.

    Order 2: ``x'' = rate^2 (u - x) - 2 zeta rate x'``; order 1: ``x' = rate (u - x)`` (the
    second state unused). From the matrix exponential of the system augmented with the input and
    its derivatives (a chain of integrators). Order 0: zeros (no state).
    """
    out = np.zeros((2, 6))
    if order == 0:
        return out
    aug = np.zeros((6, 6))
    if order == 2:
        aug[0, 1] = 1.0
        aug[1, 0], aug[1, 1], aug[1, 2] = -rate * rate, -2.0 * zeta * rate, rate * rate
    else:
        aug[0, 0], aug[0, 2] = -rate, rate
    aug[2, 3] = aug[3, 4] = aug[4, 5] = 1.0  # u' = u1, u1' = u2, u2' = u3
    out[:] = _expm(aug * h)[:2]
    return out


def _expm(a: np.ndarray) -> np.ndarray:
    """Matrix exponential of a small matrix: Taylor series to 18 terms after scaling to norm <= 1/2,
    then squaring (scipy's Pade expm costs 20 to 100 times more for a 6 x 6, called per evaluation)."""
    norm = float(np.max(np.sum(np.abs(a), axis=1)))
    squarings = max(0, math.ceil(math.log2(norm)) + 1) if norm > 0 else 0
    scaled = a / 2.0**squarings
    term = np.eye(len(a))
    out = term.copy()
    for k in range(1, 19):
        term = term @ scaled / k
        out += term
    for _ in range(squarings):
        out = out @ out
    return out
