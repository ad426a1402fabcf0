"""Accuracy of a substructured test from its synchronisation signals (section 4).

The target is the numerical model's displacement ``y*`` and the measured
response the actuator displacement ``x`` (LVDT). Perfect transfer puts the
trajectory ``(y*, x)`` on the synchronisation subspace ``x = y*`` (the 45
degree line of Fig. 12a); the synchronisation error is ``e = y* - x``.

Metrics
-------
* Table I ratio: ``max|e| / max|y*|`` in percent.
* Tracking indices of the RTHS benchmark (Silva et al. 2020):
  J1, the delay [s] at the peak of the cross-correlation of ``y*`` and ``x``
  (positive: ``x`` lags), refined to a fraction of a sample by a parabola
  through the peak; J2 = ``100 rms(e) / rms(y*)`` [%]; J3 = ``100 max|e| /
  max|y*|`` [%] (the same number as the Table I ratio).
* Online delay estimate (Wallace et al. [28]): J1 over a sliding window that
  uses only past samples, reported as a time series.
* Welch PSD of ``e`` (Fig. 12c) and its peaks: the highest within the band of
  the test's dynamics (:data:`DYNAMICS_BAND`, 0-20 Hz), which is what the
  paper's Fig. 12(c) reads (the forcing frequency, where delay and amplitude
  errors of the control show), and separately the highest above it (sensor
  noise, actuator dynamics). Each peak comes with its level over the median
  of its band [dB]: a few dB is the scatter of broadband noise, with no
  dominant frequency; a tone stands tens of dB out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import signal

from ..errors import ConfigError, ResultsError

#: Table I of the paper: (max sync error [m], max target [m], ratio [%]).
TABLE_I = {"PO": (0.0007, 0.0181, 3.9), "CO": (0.0016, 0.0405, 3.9)}
#: Upper edge [Hz] of the band of the test's dynamics: the forcing (2-3 Hz) and its harmonics, the
#: oscillator (2.1 Hz) and the pendulum. Above it lie sensor noise and the actuator's own dynamics.
DYNAMICS_BAND = 20.0


def _pair(y_star, x) -> tuple[np.ndarray, np.ndarray]:
    y_star = np.asarray(y_star, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if y_star.shape != x.shape or y_star.ndim != 1 or y_star.size < 3:
        raise ConfigError(f"y* and x must be 1-D of equal length >= 3; got {y_star.shape} and {x.shape}")
    if not (np.all(np.isfinite(y_star)) and np.all(np.isfinite(x))):
        raise ConfigError("y* and x must be finite")
    return y_star, x


def sync_ratio(y_star, x) -> float:
    """Table I metric ``100 max|y* - x| / max|y*|`` [%]."""
    y_star, x = _pair(y_star, x)
    return 100.0 * float(np.max(np.abs(y_star - x)) / np.max(np.abs(y_star)))


def xcorr_delay(y_star, x, dt: float, max_lag: float = 0.1) -> float:
    """Delay [s] of ``x`` behind ``y*`` at the peak of their cross-correlation.

    The correlation is the Pearson coefficient between a fixed inner segment
    of ``x`` and ``y*`` shifted by each lag up to ``max_lag`` [s] either way;
    its peak is refined by a parabola through three samples. The coefficient
    reaches 1 exactly where the shifted ``y*`` matches ``x``, so a pure delay is
    found without the bias of a plain correlation sum (up to 0.7 ms at 1 ms
    steps from 1 s windows, depending on the signal's phase).
    """
    y_star, x = _pair(y_star, x)
    n = y_star.size
    k = max(1, min(int(round(max_lag / dt)), (n - 3) // 2))
    m = n - 2 * k
    xc = x[k : n - k] - x[k : n - k].mean()
    # s = k - lag indexes the start of the y* segment paired with the x segment
    raw = signal.correlate(y_star, xc, mode="valid", method="fft")
    c1 = np.concatenate(([0.0], np.cumsum(y_star)))
    c2 = np.concatenate(([0.0], np.cumsum(y_star * y_star)))
    s1 = c1[m:] - c1[:-m]
    s2 = c2[m:] - c2[:-m]
    var = np.maximum(s2 - s1 * s1 / m, 1e-300)
    r = (raw / np.sqrt(var * max(float(xc @ xc), 1e-300)))[::-1]  # now indexed by lag + k
    i = int(np.argmax(r))
    frac = 0.0
    if 0 < i < r.size - 1:
        c0, c1_, c2_ = r[i - 1], r[i], r[i + 1]
        denom = c0 - 2.0 * c1_ + c2_
        if denom != 0.0:
            frac = 0.5 * (c0 - c2_) / denom
    return (i - k + frac) * dt


@dataclass(frozen=True)
class TrackingIndices:
    """J1 delay [s], J2 normalised rms error [%], J3 normalised peak error [%]."""

    J1: float
    J2: float
    J3: float


def tracking_indices(y_star, x, dt: float, max_lag: float = 0.1) -> TrackingIndices:
    """J1, J2 and J3 of the RTHS benchmark (see the module docstring)."""
    y_star, x = _pair(y_star, x)
    e = y_star - x
    j2 = 100.0 * float(np.sqrt(np.mean(e * e)) / np.sqrt(np.mean(y_star * y_star)))
    return TrackingIndices(xcorr_delay(y_star, x, dt, max_lag), j2, sync_ratio(y_star, x))


def online_delay(y_star, x, dt: float, window: float = 1.0, every: float = 0.1, max_lag: float = 0.05) -> pd.DataFrame:
    """Sliding-window cross-correlation delay estimate, causal.

    Returns a frame with ``t`` (end of each window [s], relative to the first
    sample) and ``delay`` [s], one row every ``every`` seconds.
    """
    y_star, x = _pair(y_star, x)
    nw = int(round(window / dt))
    step = max(1, int(round(every / dt)))
    if nw < 3 or nw > y_star.size:
        raise ConfigError(f"window = {window:g} s must hold between 3 and {y_star.size} samples of dt = {dt:g} s")
    ends = np.arange(nw, y_star.size + 1, step)
    delays = [xcorr_delay(y_star[e - nw : e], x[e - nw : e], dt, max_lag) for e in ends]
    return pd.DataFrame({"t": (ends - 1) * dt, "delay": delays})


def error_psd(error, dt: float, segment: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD of the sync error: frequencies [Hz] and density [m^2/Hz] (Hann, 50% overlap)."""
    e = np.asarray(error, dtype=np.float64)
    nper = min(e.size, int(round(segment / dt)))
    return signal.welch(e, fs=1.0 / dt, nperseg=nper, detrend="constant")


@dataclass(frozen=True)
class PsdPeak:
    """The highest bin of a PSD within ``[low, high]`` Hz.

    Attributes
    ----------
    frequency : float
        Where it lies [Hz].
    level_db : float
        Its height over the median PSD of the band [dB]: a few dB for
        broadband noise, tens of dB for a tone.
    low, high : float
        The band [Hz].
    """

    frequency: float
    level_db: float
    low: float
    high: float

    def text(self, digits: int = 3) -> str:
        """``2.200 Hz in 0-20 Hz, 61 dB over the band's median`` (``digits`` after the point)."""
        return (
            f"{self.frequency:.{digits}f} Hz in {self.low:g}-{self.high:g} Hz, "
            f"{self.level_db:.0f} dB over the band's median"
        )


def psd_peak(f: np.ndarray, pxx: np.ndarray, low: float, high: float) -> PsdPeak | None:
    """The highest bin of ``pxx`` with ``low < f <= high`` (the 0 Hz bin, the mean, never counts); None if none."""
    inside = (f > max(low, 0.0)) & (f <= high)
    if not inside.any():
        return None
    band, levels = f[inside], pxx[inside]
    i = int(np.argmax(levels))
    top, median = float(levels[i]), float(np.median(levels))
    if top <= 0.0:  # no error at all in the band: nothing stands out
        level = 0.0
    elif median <= 0.0:  # zeros but for a few bins: those stand out without bound
        level = math.inf
    else:
        level = 10.0 * math.log10(top / median)
    return PsdPeak(float(band[i]), level, low, high)


@dataclass(frozen=True)
class SyncReport:
    """Everything ``pendsweep sync`` prints for one trace.

    ``peak`` is the error PSD's peak within :data:`DYNAMICS_BAND`,
    ``high_peak`` its peak above it (None when the sampling rate gives no
    frequency above it).
    """

    max_error: float
    max_target: float
    ratio: float
    indices: TrackingIndices
    delay_online: pd.DataFrame
    peak: PsdPeak
    high_peak: PsdPeak | None

    def lines(self, reference: str | None = None) -> list[str]:
        out = [
            f"max |y* - x|         {self.max_error:.4g} m",
            f"max |y*|             {self.max_target:.4g} m",
            f"Table I ratio        {self.ratio:.2f} %",
            f"J1 (xcorr delay)     {1e3 * self.indices.J1:.2f} ms",
            f"J2 (rms error)       {self.indices.J2:.2f} %",
            f"J3 (peak error)      {self.indices.J3:.2f} %",
            f"online delay         median {1e3 * self.delay_online['delay'].median():.2f} ms, "
            f"range {1e3 * self.delay_online['delay'].min():.2f} to {1e3 * self.delay_online['delay'].max():.2f} ms",
            f"error PSD peak       {self.peak.text()}",
        ]
        if self.high_peak is not None:
            out.append(f"error PSD HF peak    {self.high_peak.text(1)}")
        if reference in TABLE_I:
            e, t, r = TABLE_I[reference]
            out.append(f"paper, Table I {reference}   max error {e} m, max target {t} m, ratio {r} %")
        return out


def analyse(trace: pd.DataFrame, window: float = 1.0) -> SyncReport:
    """Sync metrics of a trace with columns ``t``, ``y`` (= y*) and ``x_meas``."""
    missing = {"t", "y", "x_meas"} - set(trace.columns)
    if missing:
        raise ResultsError(f"trace lacks column(s) {', '.join(sorted(missing))}; write it with `pendsweep trace`")
    t = trace["t"].to_numpy()
    if t.size < 16:
        raise ResultsError(f"trace has only {t.size} samples; need at least 16")
    dt = float(np.median(np.diff(t)))
    y_star = trace["y"].to_numpy()
    x = trace["x_meas"].to_numpy()
    e = y_star - x
    f, pxx = error_psd(e, dt)
    # the band of the dynamics as far as the sampling resolves it (a very short trace: its first bin)
    band = max(min(DYNAMICS_BAND, float(f[-1])), float(f[1]))
    return SyncReport(
        max_error=float(np.max(np.abs(e))),
        max_target=float(np.max(np.abs(y_star))),
        ratio=sync_ratio(y_star, x),
        indices=tracking_indices(y_star, x, dt),
        delay_online=online_delay(y_star, x, dt, window=min(window, 0.5 * t.size * dt)),
        peak=psd_peak(f, pxx, 0.0, band),
        high_peak=psd_peak(f, pxx, band, float(f[-1])),
    )
