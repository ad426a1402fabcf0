"""Polynomial forward prediction of a sampled signal (the paper's delay compensation)."""

from __future__ import annotations

import numpy as np

#: Highest polynomial order offered for the prediction.
MAX_PREDICTOR_ORDER = 4


def predictor_weights(order: int, points: int, horizon: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares polynomial extrapolation as two weight vectors.

    The polynomial of ``order`` fitted to ``points`` samples at times
    ``0, -dt, ..., -(points-1) dt`` (most recent first) is evaluated at
    ``horizon`` [s]: value ``= w @ samples`` and slope ``= wd @ samples`` [1/s].

    Returns
    -------
    w, wd : float64[points]
        Contiguous weight vectors.
    """
    s = -np.arange(points, dtype=np.float64)  # sample times in units of dt
    V = np.vander(s, order + 1, increasing=True)
    P = np.linalg.pinv(V)  # (order+1, points): coefficients from samples
    hs = horizon / dt
    powers = np.array([hs**j for j in range(order + 1)])
    dpowers = np.array([j * hs ** (j - 1) if j > 0 else 0.0 for j in range(order + 1)])
    return np.ascontiguousarray(powers @ P), np.ascontiguousarray(dpowers @ P / dt)
