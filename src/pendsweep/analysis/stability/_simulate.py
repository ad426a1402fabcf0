"""Critical delay measured on the substructured backend, as the paper did.

Section 2.4: "the stability boundary points were then located by
artificially increasing the delay ... until the instability frequency
appears". Here the pendulum hangs at rest with no forcing, the numerical
model starts from a small displacement, and every source of noise,
quantisation and compensation is off unless asked for. Each run's growth
rate and frequency come from the peaks of ``y*``; the delay is increased in
steps until the growth rate turns positive, and the critical delay is where
the linear interpolation of the growth rate between the last stable and the
first unstable delay crosses zero.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import find_peaks

from ...backends import make_backend
from ...errors import ConfigError
from ...model.params import ModelParams

__all__ = ["QUIET", "Growth", "SimulatedMargin", "simulated_growth", "simulated_delay_margin"]

#: Backend options that switch off noise, quantisation and vibration.
QUIET = dict(
    force_noise=0.0,
    harmonic3=0.0,
    harmonic5=0.0,
    harmonic7=0.0,
    encoder_resolution=0.0,
    lvdt_resolution=0.0,
    lvdt_noise=0.0,
)


@dataclass(frozen=True)
class Growth:
    """Exponential growth rate [1/s] and frequency [rad/s] of ``y*`` at one delay [s]."""

    tau: float
    sigma: float
    omega: float


@dataclass(frozen=True)
class SimulatedMargin:
    """Critical transport delay [s] found by simulation, its frequency [rad/s] and the runs."""

    tau_star: float
    omega_star: float
    runs: tuple[Growth, ...]


def simulated_growth(
    params: ModelParams,
    tau: float,
    duration: float = 4.0,
    settle: float = 0.5,
    y0: float = 1e-3,
    **options,
) -> Growth:
    """Growth rate and frequency of the free response at transport delay ``tau`` [s].

    Parameters
    ----------
    params : ModelParams
        The rig; use ``alpha = 0`` (no forcing).
    tau : float
        Transport delay [s].
    duration : float
        Simulated time [s], rounded up to whole forcing periods.
    settle : float
        Initial time [s] left out of the fit, while the faster modes die out.
    y0 : float
        Initial displacement of the numerical model [m].
    **options
        Substructured-backend options (``actuator``, ``predictor_order``, ...),
        added to :data:`QUIET`.
    """
    if params.alpha != 0.0:
        raise ConfigError(f"alpha = {params.alpha:g} N: the free response needs alpha = 0")
    backend = make_backend("substructured", **{**QUIET, **options, "transport_delay": tau})
    periods = int(math.ceil(duration * params.fe))
    df = backend.trace(params, backend.initial_state(params, y0, 0.0, 0.0, 0.0), periods)
    t, y = df["t"].to_numpy(), df["y"].to_numpy()
    peaks, _ = find_peaks(y)
    peaks = peaks[t[peaks] > settle]
    if peaks.size < 3:
        raise ConfigError(f"too few oscillation peaks after {settle:g} s to fit a growth rate at tau = {tau:g} s")
    sigma = float(np.polyfit(t[peaks], np.log(np.abs(y[peaks])), 1)[0])
    omega = 2.0 * math.pi / float(np.mean(np.diff(t[peaks])))
    return Growth(float(tau), sigma, omega)


def simulated_delay_margin(
    params: ModelParams, tau_start: float, tau_step: float, max_runs: int = 20, **options
) -> SimulatedMargin:
    """Raise the transport delay from ``tau_start`` by ``tau_step`` [s] until ``y*`` grows.

    ``tau_start`` must be a stable delay. Raises ConfigError when no
    instability appears within ``max_runs`` runs.
    """
    runs = [simulated_growth(params, tau_start, **options)]
    if runs[0].sigma >= 0.0:
        raise ConfigError(f"the loop already grows at the starting delay {tau_start:g} s; start lower")
    for i in range(1, max_runs):
        runs.append(simulated_growth(params, tau_start + i * tau_step, **options))
        if runs[-1].sigma >= 0.0:
            a, b = runs[-2], runs[-1]
            tau = a.tau + (b.tau - a.tau) * (-a.sigma) / (b.sigma - a.sigma)
            return SimulatedMargin(tau, b.omega, tuple(runs))
    raise ConfigError(f"no instability up to tau = {runs[-1].tau:g} s")
