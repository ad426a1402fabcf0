"""The band-pass force filter and its phase lag expressed as a delay."""

from __future__ import annotations

import numpy as np

from .delay import phase_to_delay


def design_force_filter(low: float, high: float, order: int, dt: float) -> np.ndarray:
    """Butterworth band-pass ``[low, high]`` Hz at sample step ``dt`` [s] as SOS, shape ``(order, 6)``."""
    from scipy import signal  # imported on use: scipy.signal costs a second at start-up

    return np.ascontiguousarray(signal.butter(order, [low, high], btype="bandpass", fs=1.0 / dt, output="sos"))


def filter_phase(sos: np.ndarray, frequency: float, dt: float) -> float:
    """Phase [rad] of the filter at ``frequency`` [Hz] (negative: lag)."""
    from scipy import signal

    _, hresp = signal.sosfreqz(sos, worN=[frequency], fs=1.0 / dt)
    return float(np.angle(hresp[0]))


def filter_delay(sos: np.ndarray, frequency: float, dt: float) -> float:
    """Equivalent delay [s] of the filter's phase lag at ``frequency`` [Hz]."""
    return phase_to_delay(filter_phase(sos, frequency, dt), frequency)
