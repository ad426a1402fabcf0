"""Delays of the transfer system: how far the actuator's ``x`` lags the command ``y*``."""

from __future__ import annotations

import math

#: Transfer-system models: a servo (second order after a transport delay and the
#: command's zero-order hold), a pure delay, and the ideal (delay-free) actuator.
ACTUATORS = ("servo", "delay", "ideal")


def effective_delay(
    actuator: str, transport_delay: float, servo_bandwidth: float, servo_damping: float, dt: float, frequency: float
) -> float:
    """Total effective delay [s] of ``x`` behind ``y*`` at ``frequency`` [Hz].

    Servo: transport delay + ``dt/2`` (zero-order hold of the command) + the
    servo's phase lag divided by the angular frequency (``servo_bandwidth``
    [Hz], ``servo_damping`` [-]). Delay actuator: the transport delay [s].
    Ideal: 0.
    """
    if actuator == "ideal":
        return 0.0
    if actuator == "delay":
        return transport_delay
    w = 2.0 * math.pi * frequency
    ws = 2.0 * math.pi * servo_bandwidth
    lag = math.atan2(2.0 * servo_damping * ws * w, ws * ws - w * w)
    return transport_delay + 0.5 * dt + lag / w


def prediction_horizon(tau_hat: float | None, matched: float) -> float:
    """The predictor's horizon [s]: ``tau_hat``, or the ``matched`` total effective delay when None."""
    return matched if tau_hat is None else tau_hat


def phase_to_delay(phase: float, frequency: float) -> float:
    """Equivalent delay [s] of a phase shift [rad] at ``frequency`` [Hz]: ``-phase / (2 pi f)``."""
    return -phase / (2.0 * math.pi * frequency)
