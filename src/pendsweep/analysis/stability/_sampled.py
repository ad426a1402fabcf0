"""The loop as the substructured backend runs it: exact in discrete time.

The backend (see :mod:`pendsweep.backends.substructured`) is a sampled-data
loop with controller step ``dt``. Every element is linear while the pendulum
hangs at rest, so one controller tick is a linear map and the loop has an
exact pulse transfer function ``L(z)``; its closed-loop multipliers are the
roots of ``den(z) + num(z)``. Tick ``k``, in the backend's order:

1. load cell: the mean of ``F_s = m_s x'' + C2 x'`` over the last tick (the
   backend's integrating ADC), ``F_k = (P_k - P_{k-1})/dt`` with the momentum
   ``P = m_s x' + C2 x``; optionally band-passed (Butterworth SOS) and
   predicted forward by the filter's equivalent delay. (A point sample of
   ``x''`` just before the servo's command step would feed back a spurious
   ``-m_s ws^2 dt/2`` of damping and destabilise the loop without delay.)
2. RK4 of ``M1 y'' + C1 y' + K y = -F_k`` over ``[t_k, t_k+1]`` with ``F_k``
   held: ``(y, y')_{k+1} = Phi (y, y')_k - Gamma F_k`` (RK4 of a linear ODE
   with constant input is its degree-4 Taylor map, so this is exact);
3. command ``c_k+1`` = least-squares polynomial (order n, N points) through
   the last ``y*`` samples extrapolated by ``tau_hat`` (or ``y*_k+1``), with
   its slope;
4. actuator, with transport delay ``tau = d dt + delta`` (``0 <= delta < dt``):

   * ``"servo"``: zero-order hold ``u = c_k`` on ``[t_k, t_k+1)`` delayed by
     ``tau``, then ``G(s) = ws^2/(s^2 + 2 zeta ws s + ws^2)``. Over one tick
     ``u`` is ``c_{k-d-1}`` for ``delta`` and ``c_{k-d}`` after, so the servo
     state obeys ``xi_{k+1} = Phi_a xi_k + Gamma_1 c_{k-d-1} + Gamma_0 c_{k-d}``
     (exact matrix exponentials);
   * ``"delay"``/``"ideal"``: ``x(t) = H(t - tau)``, the cubic Hermite
     interpolant of the commands and their slopes, so ``F_k`` is a fixed
     combination of ``c, c'`` at ticks ``k-d-1`` and ``k-d``.

The only approximation left is the backend's own rig substep (0.1 ms), which
resolves the fractional delay to one substep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy import signal

from ...errors import ConfigError
from ...model.loop import (
    ACTUATORS,
    MAX_PREDICTOR_ORDER,
    design_force_filter,
    effective_delay,
    filter_delay,
    prediction_horizon,
    predictor_weights,
)
from ...model.params import LoopParams

__all__ = ["SampledLoop", "SampledMargin", "open_loop", "sampled_response", "multipliers", "sampled_delay_margin"]

Rational = tuple[np.ndarray, np.ndarray]  # (numerator, denominator), descending powers of z


@dataclass(frozen=True)
class SampledLoop:
    """Transfer system and compensation of the substructured backend.

    Attributes mirror the backend's options of the same names.

    Attributes
    ----------
    dt : float
        Controller step [s].
    actuator : {"servo", "delay", "ideal"}
        ``"delay"`` is the paper's pure delay (Hermite-interpolated command);
        ``"ideal"`` ignores the transport delay.
    servo_bandwidth : float
        Servo natural frequency [Hz].
    servo_damping : float
        Servo damping ratio [-].
    predictor_order : int
        Polynomial order 0-4 of the forward prediction of ``y*``; -1: none.
    predictor_points : int
        Samples N in the fit, ``>= predictor_order + 1``.
    tau_hat : float or None
        Prediction horizon [s]; None: matched, the total effective delay of the
        transfer system at ``filter_frequency`` (the transport delay for the
        ``"delay"`` actuator; transport + hold + servo lag for ``"servo"``), as
        in the backend (:func:`pendsweep.model.loop.prediction_horizon`).
    filter_band : (float, float) or None
        Butterworth band-pass edges of the force filter [Hz]; None: no filter.
    filter_order : int
        Butterworth order of the band-pass.
    filter_frequency : float
        Design frequency [Hz]: the filter's phase lag there becomes the horizon
        of the force prediction, and a matched ``tau_hat`` is the effective
        delay there (the backend uses the forcing frequency for both).
    """

    dt: float = 1e-3
    actuator: str = "delay"
    servo_bandwidth: float = 30.0
    servo_damping: float = 0.7
    predictor_order: int = -1
    predictor_points: int = 5
    tau_hat: float | None = None
    filter_band: tuple[float, float] | None = None
    filter_order: int = 1
    filter_frequency: float = 2.5

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ConfigError(f"dt = {self.dt!r} s must be finite and > 0")
        if self.actuator not in ACTUATORS:
            raise ConfigError(f"actuator = {self.actuator!r}; choose one of {', '.join(ACTUATORS)}")
        if not (self.servo_bandwidth > 0 and self.servo_damping > 0):
            raise ConfigError(
                f"servo_bandwidth = {self.servo_bandwidth!r} Hz and servo_damping = "
                f"{self.servo_damping!r} must both be > 0"
            )
        if not -1 <= self.predictor_order <= MAX_PREDICTOR_ORDER:
            raise ConfigError(
                f"predictor_order = {self.predictor_order!r}; accepted: -1 (none) or 0..{MAX_PREDICTOR_ORDER}"
            )
        if self.predictor_points < max(self.predictor_order + 1, 1):
            raise ConfigError(
                f"predictor_points = {self.predictor_points!r} must be >= predictor_order + 1 "
                f"= {self.predictor_order + 1}"
            )
        if self.tau_hat is not None and not (math.isfinite(self.tau_hat) and self.tau_hat >= 0):
            raise ConfigError(f"tau_hat = {self.tau_hat!r} s must be finite and >= 0")
        if self.filter_band is not None:
            low, high = self.filter_band
            if not 0 < low < high < 0.5 / self.dt:
                raise ConfigError(
                    f"filter band [{low!r}, {high!r}] Hz must satisfy 0 < low < high < Nyquist {0.5 / self.dt:g} Hz"
                )

    @property
    def predicts(self) -> bool:
        return self.predictor_order >= 0


@dataclass(frozen=True)
class SampledMargin:
    """Critical transport delay of the sampled loop.

    Attributes
    ----------
    tau_star : float or None
        Smallest transport delay [s] with a closed-loop multiplier on the unit circle.
    omega_star : float or None
        Its frequency ``|arg z| / dt`` [rad/s].
    reason : str
        What was found, in words.
    """

    tau_star: float | None
    omega_star: float | None
    reason: str


def _mul(*terms: Rational) -> Rational:
    num, den = np.array([1.0]), np.array([1.0])
    for n, d in terms:
        num, den = np.polymul(num, n), np.polymul(den, d)
    return num, den


def _delay(steps: int) -> Rational:
    """``z^-steps``."""
    return np.array([1.0]), np.concatenate([[1.0], np.zeros(steps)])


def _fir(weights: np.ndarray) -> Rational:
    """``sum_i w_i z^-i`` over ``i = 0 .. len(w)-1``."""
    return np.asarray(weights, dtype=float), _delay(len(weights) - 1)[1]


def _model(loop: LoopParams, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Numerators of ``F -> y*`` and ``F -> y*'`` and their common denominator (RK4, F held)."""
    A = np.array([[0.0, 1.0], [-loop.K / loop.M1, -loop.C1 / loop.M1]])
    hA = dt * A
    I = np.eye(2)
    Phi = I + hA @ (I + hA / 2 @ (I + hA / 3 @ (I + hA / 4)))
    Gam = dt * (I + hA / 2 @ (I + hA / 3 @ (I + hA / 4))) @ np.array([[0.0], [1.0 / loop.M1]])
    ny, den = signal.ss2tf(Phi, Gam, np.array([[1.0, 0.0]]), [[0.0]])
    nv, _ = signal.ss2tf(Phi, Gam, np.array([[0.0, 1.0]]), [[0.0]])
    return ny[0], nv[0], den


def _servo_terms(loop: LoopParams, cfg: SampledLoop, delta: float) -> Rational:
    """Servo, command -> momentum ``P_k``, for a fractional delay ``delta``; needs ``z^-(d+1)``."""
    ws = 2.0 * math.pi * cfg.servo_bandwidth
    A = np.array([[0.0, 1.0], [-ws * ws, -2.0 * cfg.servo_damping * ws]])
    B = np.array([0.0, ws * ws])

    def hold(t: float) -> tuple[np.ndarray, np.ndarray]:
        aug = np.zeros((3, 3))
        aug[:2, :2], aug[:2, 2] = A, B
        E = scipy.linalg.expm(aug * t)
        return E[:2, :2], E[:2, 2:]

    Phi_late, gam0 = hold(cfg.dt - delta)
    Phi_early, gam_early = hold(delta)
    momentum = np.array([[loop.C2, loop.ms]])
    n1, den = signal.ss2tf(Phi_late @ Phi_early, Phi_late @ gam_early, momentum, [[0.0]])
    n0, _ = signal.ss2tf(Phi_late @ Phi_early, gam0, momentum, [[0.0]])
    return np.polyadd(n1[0], np.polymul(n0[0], [1.0, 0.0])), den


def _hermite_terms(loop: LoopParams, dt: float, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """Momentum ``P_k`` from ``(c, c')`` at ticks ``k-d-1`` (older) and ``k-d``.

    Returns ``(p_c, p_cd)``, polynomials in z with ``P = z^-(d+1) [p_c C + p_cd C']``.
    """
    s = 1.0 - delta / dt
    x = np.array([2 * s**3 - 3 * s * s + 1, (s**3 - 2 * s * s + s) * dt, -2 * s**3 + 3 * s * s, (s**3 - s * s) * dt])
    xd = np.array([6 * s * s - 6 * s, (3 * s * s - 4 * s + 1) * dt, -6 * s * s + 6 * s, (3 * s * s - 2 * s) * dt]) / dt
    f = loop.ms * xd + loop.C2 * x  # coefficients of c_old, c'_old, c_new, c'_new
    return np.array([f[2], f[0]]), np.array([f[3], f[1]])


def open_loop(loop: LoopParams, tau: float, cfg: SampledLoop) -> Rational:
    """Pulse transfer function ``L(z)`` with closed loop ``1 + L(z) = 0``.

    Parameters
    ----------
    loop : LoopParams
    tau : float
        Transport delay [s], >= 0 (ignored by the ideal actuator).
    cfg : SampledLoop

    Returns
    -------
    (num, den) : ndarray
        Polynomial coefficients in descending powers of ``z``.
    """
    dt = cfg.dt
    tau = 0.0 if cfg.actuator == "ideal" else float(tau)
    d = int(math.floor(tau / dt + 1e-9))
    delta = max(tau - d * dt, 0.0)
    ny, nv, dm = _model(loop, dt)
    if cfg.predicts:
        matched = effective_delay(cfg.actuator, tau, cfg.servo_bandwidth, cfg.servo_damping, dt, cfg.filter_frequency)
        horizon = prediction_horizon(cfg.tau_hat, matched)
        w, wd = predictor_weights(cfg.predictor_order, cfg.predictor_points, horizon, dt)
        to_c, to_cd = _mul((ny, dm), _fir(w)), _mul((ny, dm), _fir(wd))
    else:
        to_c, to_cd = (ny, dm), (nv, dm)
    if cfg.actuator == "servo":
        L = _mul(to_c, _servo_terms(loop, cfg, delta), _delay(d + 1))
    else:
        pc, pcd = _hermite_terms(loop, dt, delta)
        # to_c and to_cd share their denominator by construction
        num = np.polyadd(np.polymul(pc, to_c[0]), np.polymul(pcd, to_cd[0]))
        L = _mul((num, to_c[1]), _delay(d + 1))
    L = _mul(L, (np.array([1.0, -1.0]) / dt, np.array([1.0, 0.0])))  # F_k = (P_k - P_k-1)/dt
    if cfg.filter_band is not None:
        sos = design_force_filter(cfg.filter_band[0], cfg.filter_band[1], cfg.filter_order, dt)
        parts = [(sec[:3], sec[3:]) for sec in sos]
        if cfg.predicts:
            f = cfg.filter_frequency
            lag = filter_delay(sos, f, dt)
            parts.append(_fir(predictor_weights(cfg.predictor_order, cfg.predictor_points, lag, dt)[0]))
        L = _mul(L, *parts)
    return L


def sampled_response(loop: LoopParams, tau: float, cfg: SampledLoop, omega: np.ndarray) -> np.ndarray:
    """``L(e^{i omega dt})`` at angular frequencies ``omega`` [rad/s]; shape of ``omega``."""
    num, den = open_loop(loop, tau, cfg)
    z = np.exp(1j * np.asarray(omega, dtype=float) * cfg.dt)
    return np.polyval(num, z) / np.polyval(den, z)


def multipliers(loop: LoopParams, tau: float, cfg: SampledLoop) -> np.ndarray:
    """Closed-loop multipliers (roots of ``den + num``), by decreasing modulus."""
    num, den = open_loop(loop, tau, cfg)
    roots = np.roots(np.polyadd(den, num))
    return roots[np.argsort(-np.abs(roots))]


def sampled_delay_margin(loop: LoopParams, cfg: SampledLoop, tau_max: float, tol: float = 1e-7) -> SampledMargin:
    """Smallest transport delay [s] at which the sampled loop loses stability.

    Scans ``[0, tau_max]`` in steps of ``dt`` for the first delay with a
    multiplier of modulus >= 1, then bisects to ``tol`` [s].
    """

    def radius(tau: float) -> float:
        return float(np.abs(multipliers(loop, tau, cfg)[0]))

    if radius(0.0) >= 1.0:
        return SampledMargin(0.0, _frequency(loop, 0.0, cfg), "unstable already without transport delay")
    if cfg.actuator == "ideal":
        return SampledMargin(None, None, "the ideal actuator has no transport delay and the loop is stable")
    lo = 0.0
    for hi in np.arange(cfg.dt, tau_max + cfg.dt, cfg.dt):
        if radius(hi) >= 1.0:
            break
        lo = float(hi)
    else:
        return SampledMargin(None, None, f"stable for every transport delay up to {tau_max:g} s")
    hi = float(hi)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if radius(mid) >= 1.0:
            hi = mid
        else:
            lo = mid
    w = _frequency(loop, hi, cfg)
    return SampledMargin(hi, w, f"a multiplier leaves the unit circle at tau* = {hi:.6g} s, omega* = {w:.5g} rad/s")


def _frequency(loop: LoopParams, tau: float, cfg: SampledLoop) -> float:
    return float(abs(np.angle(multipliers(loop, tau, cfg)[0])) / cfg.dt)
