"""Signal helpers shared by the diagnosis's stages: sensor noise, quantisation, smoothing, midpoints.

No stage of its own: the transfer identification, the replays, the damping appendix and the
residual signatures read their records' channels with these.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import maximum_filter1d, minimum_filter1d
from scipy.signal import savgol_coeffs, savgol_filter

#: Largest platform displacement a record may hold [m]: the rig's stroke is centimetres, so a larger one
#: is a unit error (millimetres read as metres).
MAX_STROKE = 1.0
#: Savitzky-Golay window for state estimates [s] (cubic).
SMOOTH_WINDOW = 0.05


def noise_std(x: np.ndarray) -> float:
    """Sensor-noise standard deviation of a finely sampled channel.

    Third differences remove the smooth signal (its contribution scales as
    ``(omega dt)^3``); white noise of variance s^2 gives third differences of
    variance 20 s^2.
    """
    return float(np.std(np.diff(x, 3)) / math.sqrt(20.0))


def rounding_std(x: np.ndarray, window: int) -> float:
    """One-sigma rounding error of a quantised channel over the record [unit of x].

    A reading rounded to steps ``q`` errs uniformly within half a step while the
    signal crosses levels (variance ``q^2 / 12``), however slowly it moves; third
    differences see that error only at the steps themselves, so
    :func:`noise_std` misses it on a slow signal (a small pendulum swing read in
    a few encoder steps: 4e-5 rad against q / sqrt(12) = 3.8e-4). The share of
    samples whose ``window`` holds a change of level weights it: a reading that
    stays on one level is exact for a model that holds it. ``q`` is the
    smallest change between samples (an unquantised channel's is tiny, and so
    is its rounding error).
    """
    steps = np.abs(np.diff(x))
    if not np.any(steps > 0):
        return 0.0
    quantum = float(steps[steps > 0].min())
    changing = maximum_filter1d(x, window) != minimum_filter1d(x, window)
    return quantum / math.sqrt(12.0) * math.sqrt(float(np.mean(changing)))


def smooth_window(n: int, dt: float) -> int:
    """Samples of the Savitzky-Golay window of :func:`smoothed` for ``n`` samples of step ``dt`` (odd)."""
    w = max(5, int(round(SMOOTH_WINDOW / dt)) | 1)
    return min(w, n - 1 + n % 2)


def smoothed(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Savitzky-Golay estimates of ``x`` and its derivative [unit/s]."""
    w = smooth_window(len(x), dt)
    return savgol_filter(x, w, 3), savgol_filter(x, w, 3, deriv=1, delta=dt)


def smoothing_gain(n: int, dt: float, at: np.ndarray) -> np.ndarray:
    """How much white noise of unit variance moves :func:`smoothed`'s estimates at samples ``at``:
    (len(at), 2) standard deviations of the value [-] and of the derivative [1/s].

    The norms of the filter's coefficients, the one-sided ones within half a window of the record's
    ends (``savgol_filter``'s ``interp`` mode fits the first and last windows): a state estimated at a
    record's first sample is several times worse than one inside it.
    """
    w = smooth_window(n, dt)
    half = w // 2
    out = np.empty((len(at), 2))
    for k, i in enumerate(at):
        pos = half if half <= i < n - half else (i if i < half else w - (n - i))
        for d in (0, 1):
            out[k, d] = float(np.linalg.norm(savgol_coeffs(w, 3, deriv=d, delta=dt, pos=pos, use="dot")))
    return out


def midpoint_values(f: np.ndarray) -> np.ndarray:
    """Four-point (cubic) interpolation of ``f`` halfway between samples."""
    h = 0.5 * (f[:-1] + f[1:])
    if len(f) >= 4:
        h[1:-1] = (-f[:-3] + 9.0 * f[1:-2] + 9.0 * f[2:-1] - f[3:]) / 16.0
    return h
