"""Transfer-system identification: from the command ``y_cmd`` to the measured platform motion ``y``.

A substructured record holds both ends of the actuator: the controller's
command (exact: its own number) and the platform's displacement as the LVDT
reads it. The actuator is identified from these two channels alone, before
and apart from any model of the structure, so that no numerical-model
parameter can absorb its lag or gain (issue 22).

Models (:data:`MODELS`), each driven by ``gain x c(t - tau)`` with ``c`` the
command's cubic Hermite interpolant (:func:`pendsweep.kernels._measured.transfer_trace`):

``delay``
    ``x = gain c(t - tau)``: parameters tau [s], gain [-].
``first_order``
    ``T x' = gain c(t - tau) - x``: tau, gain, 1/T [1/s].
``second_order``
    ``x'' = ws^2 (gain c(t - tau) - x) - 2 zeta ws x'``: tau, gain, ws [rad/s], zeta [-].

Every model also fits the LVDT's offset and linear drift (eliminated
linearly, variable projection). The fit minimises the squared error between
modelled and measured displacement from :data:`SETTLE` seconds on. A model is
judged by its **held-out error**: the record is cut into blocks of
:data:`BLOCK_SECONDS`, the model is fitted on the even blocks and predicts the
odd ones, and the other way round. The selected model is the simplest whose
held-out mean square is within :data:`SELECT_MARGIN` of the best one's (a
well-damped 40 Hz servo at a 2.2 Hz forcing is a pure delay to the LVDT's
precision, and the data cannot say more).

Uncertainties are the Jacobian's of the fit on all samples, inflated for the
residual's lag-one autocorrelation rho by ``(1 + rho) / (1 - rho)``; the
effective delay and amplitude at a frequency carry the propagated covariance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ....errors import ConfigError
from ....kernels._measured import sampled_transfer_trace, transfer_trace
from ..signals import MAX_STROKE, noise_std
from .servo_step import servo_propagator

#: Transfer models by name: (order of the servo, names of the nonlinear parameters).
MODELS = {
    "delay": (0, ("tau", "gain")),
    "first_order": (1, ("tau", "gain", "rate")),
    "second_order": (2, ("tau", "gain", "rate", "zeta")),
}
#: Units of the parameters.
UNITS = {"tau": "s", "gain": "-", "rate": "1/s (first order: 1/T; second order: ws in rad/s)", "zeta": "-"}
#: Bounds of the parameters: delay [s], gain, rate [1/s], damping ratio.
BOUNDS = {
    "tau": (0.0, 0.25),
    "gain": (0.2, 5.0),
    "rate": (2.0 * math.pi * 0.5, 2.0 * math.pi * 500.0),
    "zeta": (0.05, 5.0),
}
#: Seconds at the start of a record not compared (servo transients from the assumed start at rest).
SETTLE = 0.1
#: A servo's free response is fitted only where it keeps this share of its peak into the compared samples.
FREE_RESPONSE_FLOOR = 1e-3
#: Held-out block length [s].
BLOCK_SECONDS = 1.0
#: A more complex model is selected only when its held-out mean square beats the simpler one's by this share.
SELECT_MARGIN = 0.05
#: Servo rates tried as starts [Hz] (the fit keeps the best).
RATE_STARTS_HZ = (8.0, 40.0, 200.0)


@dataclass(frozen=True)
class Actuator:
    """An actuator model: ``x = gain G(s) e^{-s tau} c`` with G of the given order.

    Attributes
    ----------
    order : int
        0 (pure delay), 1 or 2.
    tau : float
        Transport delay [s].
    gain : float
        Static gain [-].
    rate : float
        1/T [1/s] (order 1) or ws [rad/s] (order 2); unused for order 0.
    zeta : float
        Damping ratio (order 2).
    """

    order: int = 0
    tau: float = 0.0
    gain: float = 1.0
    rate: float = math.inf
    zeta: float = 0.0

    @classmethod
    def from_values(cls, name: str, values: dict[str, float]) -> Actuator:
        return cls(MODELS[name][0], **{k: float(values[k]) for k in MODELS[name][1]})

    @property
    def name(self) -> str:
        return next(n for n, (order, _) in MODELS.items() if order == self.order)

    def response(self, f: float) -> complex:
        """Frequency response x/c at ``f`` [Hz]."""
        s = 2j * math.pi * f
        servo = 1.0
        if self.order == 1:
            servo = self.rate / (s + self.rate)
        elif self.order == 2:
            servo = self.rate**2 / (s * s + 2.0 * self.zeta * self.rate * s + self.rate**2)
        return complex(self.gain * servo * np.exp(-s * self.tau))

    def effective_delay(self, f: float) -> float:
        """The delay of the response at ``f`` [s]: its phase lag over ``2 pi f`` (lags of up to one period)."""
        lag = -math.atan2(self.response(f).imag, self.response(f).real)
        # The phase wraps every period: take the lag nearest to the delay the model's parts add up to.
        approx = self.tau + (
            1.0 / self.rate if self.order == 1 else 2.0 * self.zeta / self.rate if self.order == 2 else 0.0
        )
        w = 2.0 * math.pi * f
        turns = round((approx * w - lag) / (2.0 * math.pi))
        return (lag + 2.0 * math.pi * turns) / w

    def amplitude(self, f: float) -> float:
        """|x/c| at ``f`` [Hz]."""
        return abs(self.response(f))

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"model": self.name, "tau": self.tau, "gain": self.gain}
        if self.order >= 1:
            d["rate"] = self.rate
        if self.order == 2:
            d["zeta"] = self.zeta
        return d


def nominal_actuator(meta: dict[str, Any] | None, tau: float) -> Actuator:
    """The record's nominal actuator: its metadata's ``actuator`` table, else a pure delay ``tau``.

    ``actuator = {"model": "second_order", "tau": s, "gain": -, "rate": rad/s, "zeta": -}``
    (``first_order``: ``rate`` = 1/T; ``delay``: tau and gain only).
    """
    if not meta:
        return Actuator(0, tau)
    name = meta.get("model", "delay")
    if name not in MODELS:
        raise ConfigError(f"actuator model {name!r} is unknown; accepted: {', '.join(MODELS)}")
    values = {"tau": tau, "gain": 1.0, "rate": math.inf, "zeta": 0.0}
    values.update({k: float(v) for k, v in meta.items() if k != "model"})
    for k in MODELS[name][1]:
        if not (math.isfinite(values[k]) and values[k] >= 0):
            raise ConfigError(f"actuator {k} = {values[k]!r} must be a finite number >= 0 [{UNITS[k]}]")
    return Actuator.from_values(name, values)


@dataclass
class TransferFit:
    """One transfer model fitted to a record.

    Attributes
    ----------
    actuator : Actuator
        The fitted model.
    stderr : dict
        One-sigma uncertainty of each parameter.
    covariance : ndarray
        Covariance of the parameters in the order of ``MODELS[name][1]``.
    offset, drift : float
        LVDT offset [m] and drift [m/s] (at the record's mid time).
    error_fit, error_held_out : float
        RMS error of the modelled displacement [m]: fitted on all compared samples; predicted on held-out blocks.
    achieved : ndarray
        The modelled LVDT reading at every sample (motion + offset + drift) [m].
    initial : ndarray
        Coefficients of the servo's free responses: its state at the start less rest's.
    """

    actuator: Actuator
    stderr: dict[str, float]
    covariance: np.ndarray = field(repr=False)
    offset: float
    drift: float
    error_fit: float
    error_held_out: float
    achieved: np.ndarray = field(repr=False)
    initial: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))

    @property
    def name(self) -> str:
        return self.actuator.name

    def effective_delay(self, f: float) -> tuple[float, float]:
        """Effective delay at ``f`` [Hz] and its one-sigma uncertainty [s]."""
        return self._propagate(lambda a: a.effective_delay(f))

    def amplitude(self, f: float) -> tuple[float, float]:
        """Amplitude ratio at ``f`` and its one-sigma uncertainty."""
        return self._propagate(lambda a: a.amplitude(f))

    def _propagate(self, quantity) -> tuple[float, float]:
        names = MODELS[self.name][1]
        base = {k: getattr(self.actuator, k) for k in names}
        value = quantity(self.actuator)
        grad = np.zeros(len(names))
        for i, k in enumerate(names):
            h = 1e-6 * max(abs(base[k]), 1e-3)
            grad[i] = (quantity(Actuator.from_values(self.name, dict(base, **{k: base[k] + h}))) - value) / h
        return float(value), float(math.sqrt(max(grad @ self.covariance @ grad, 0.0)))

    def to_json(self) -> dict[str, Any]:
        return {
            **self.actuator.to_dict(),
            "stderr": self.stderr,
            "lvdt_offset": self.offset,
            "lvdt_drift": self.drift,
            "error_fit": self.error_fit,
            "error_held_out": self.error_held_out,
        }


class TransferProblem:
    """The command and measured platform displacement of one record, ready for fitting.

    Parameters
    ----------
    t, command, measured : ndarray
        Sample times [s], command ``y_cmd`` [m] and LVDT reading ``y`` [m].
    shape : str
        How the actuator received the command samples (a record's ``daq.command``): ``smooth``
        (their cubic Hermite interpolant), ``ramped`` (linearly between ticks) or ``held``.
    """

    def __init__(self, t: np.ndarray, command: np.ndarray, measured: np.ndarray, shape: str = "smooth"):
        n = len(t)
        self.shape = shape
        self.dt = float((t[-1] - t[0]) / (n - 1))
        self.n = n
        self.tc = (t - t[0]) - 0.5 * (t[-1] - t[0])  # centred: offset and drift are uncorrelated
        self.command = np.ascontiguousarray(command, dtype=np.float64)
        # Central differences (a Catmull-Rom spline): a jittery command (a forward predictor's) keeps its
        # tick-to-tick shape, which a smoothed slope would round off.
        self.slope = np.ascontiguousarray(np.gradient(self.command, self.dt))
        self.measured = np.ascontiguousarray(measured, dtype=np.float64)
        start = int(math.ceil(SETTLE / self.dt))
        if n - start < 50:
            raise ConfigError(f"a transfer identification needs more than {SETTLE + 50 * self.dt:g} s of record")
        self.idx = np.arange(start, n)
        block = max(10, int(round(BLOCK_SECONDS / self.dt)))
        parity = ((self.idx - start) // block) % 2
        self.halves = [self.idx[parity == 0], self.idx[parity == 1]]
        self.noise = noise_std(self.measured)
        self.start_tau = lag_of(self.command, self.measured, self.dt)

    def motion(self, actuator: Actuator, per_sample: int = 1, initial: np.ndarray | None = None) -> np.ndarray:
        """Rows of platform x, x', x'' (``per_sample`` rows per sample step).

        ``initial``: coefficients of the servo's free responses (:meth:`free_responses`) added to the
        response from rest, i.e. the servo's state at the record's start less the state at rest.
        """
        out = self._trace(actuator, per_sample)
        if initial is not None:
            for c, free in zip(initial, self.free_responses(actuator, per_sample)):
                out += c * free
        return out

    def _trace(self, actuator: Actuator, per_sample: int, state: tuple[float, float] | None = None) -> np.ndarray:
        out = np.empty(((self.n - 1) * per_sample + 1, 3))
        order = actuator.order
        rate = actuator.rate if order else 0.0
        propagator = servo_propagator(order, rate, actuator.zeta, self.dt / per_sample)
        gain, (x0, v0) = (actuator.gain, (math.nan, 0.0)) if state is None else (0.0, state)
        if self.shape != "smooth":
            h = self.dt / per_sample
            split = math.fmod(actuator.tau, h)
            split = 0.0 if split < 1e-9 * h or split > h * (1.0 - 1e-9) else split
            first = servo_propagator(order, rate, actuator.zeta, split)
            second = servo_propagator(order, rate, actuator.zeta, h - split)
            sampled_transfer_trace(
                self.command, actuator.tau, gain, order, rate, actuator.zeta, first, second, split,
                self.shape == "ramped", self.dt, per_sample, out, x0, v0,
            )  # fmt: skip
            return out
        transfer_trace(
            self.command, self.slope, actuator.tau, gain, order, rate, actuator.zeta, propagator,
            self.dt, per_sample, out, x0, v0,
        )  # fmt: skip
        return out

    def free_responses(self, actuator: Actuator, per_sample: int = 1) -> list[np.ndarray]:
        """The servo's responses to a unit initial displacement (and, second order, velocity) without input.

        A record starts with its servo in motion, which the model's start at rest does not know; its
        initial state enters the response linearly and is fitted with the LVDT's offset and drift.
        """
        states = {0: [], 1: [(1.0, 0.0)], 2: [(1.0, 0.0), (0.0, 1.0)]}[actuator.order]
        out = []
        for state in states:
            free = self._trace(actuator, per_sample, state)
            # A fast servo has forgotten its start before the compared samples: no column to fit
            # (its coefficient would be fitted to the noise of the first samples, times e^(+rate t)).
            compared = free[self.idx[0] * per_sample :, 0]
            if np.max(np.abs(compared)) > FREE_RESPONSE_FLOOR * np.max(np.abs(free[:, 0])):
                out.append(free)
        return out

    def _residual(self, x: np.ndarray, idx: np.ndarray, free: list[np.ndarray] = ()) -> tuple[np.ndarray, np.ndarray]:
        """Measured minus modelled at ``idx`` with the best offset, drift and initial servo state
        removed (linear least squares); and their coefficients."""
        r = self.measured[idx] - x[idx]
        basis = np.stack([np.ones(len(idx)), self.tc[idx]] + [f[idx, 0] for f in free], axis=1)
        coef = np.linalg.lstsq(basis, r, rcond=None)[0]
        return r - basis @ coef, coef

    def fit(
        self, name: str, idx: np.ndarray | None = None, starts: list[dict[str, float]] | None = None
    ) -> tuple[dict[str, float], Any]:
        """Least squares of model ``name`` on samples ``idx`` (default all compared); the best of
        ``starts`` (default: :meth:`_starts`, a few servo rates decades apart)."""
        idx = self.idx if idx is None else idx
        names = MODELS[name][1]
        lo = np.array([BOUNDS[k][0] for k in names])
        hi = np.array([BOUNDS[k][1] for k in names])
        scale = np.array([{"tau": 0.005, "gain": 0.05, "rate": 1.0, "zeta": 0.1}[k] for k in names])
        best = None
        for start in starts or self._starts(name):
            u0 = np.array([start[k] for k in names])
            if "rate" in names:  # the rate is fitted on a log scale: starts decades apart
                u0[names.index("rate")] = math.log(u0[names.index("rate")])

            def residual(u: np.ndarray) -> np.ndarray:
                values = dict(zip(names, u))
                if "rate" in values:
                    values["rate"] = math.exp(values["rate"])
                actuator = Actuator.from_values(name, values)
                r, _ = self._residual(self._trace(actuator, 1)[:, 0], idx, self.free_responses(actuator))
                return np.where(np.isfinite(r), r, 1.0)

            lower, upper = lo.copy(), hi.copy()
            if "rate" in names:
                k = names.index("rate")
                lower[k], upper[k] = math.log(lo[k]), math.log(hi[k])
            u0 = np.clip(u0, lower + 1e-9 * (upper - lower), upper - 1e-9 * (upper - lower))
            res = least_squares(residual, u0, bounds=(lower, upper), x_scale=scale, method="trf")
            if best is None or res.cost < best.cost:
                best = res
        values = dict(zip(names, best.x))
        if "rate" in values:
            values["rate"] = math.exp(values["rate"])
        return values, best

    def _starts(self, name: str) -> list[dict[str, float]]:
        order = MODELS[name][0]
        if order == 0:
            return [{"tau": self.start_tau, "gain": 1.0}]
        starts = []
        for f in RATE_STARTS_HZ:
            if order == 1:
                rate = 2.0 * math.pi * f
                starts.append({"tau": max(self.start_tau - 1.0 / rate, 0.0), "gain": 1.0, "rate": rate})
            else:
                rate = 2.0 * math.pi * f
                starts.append({"tau": max(self.start_tau - 1.4 / rate, 0.0), "gain": 1.0, "rate": rate, "zeta": 0.7})
        return starts

    def evaluate(self, actuator: Actuator) -> TransferFit:
        """``actuator`` as given (no dynamics fitted; the LVDT's offset, drift and the servo's initial
        state fitted linearly); its error on all compared samples serves as its held-out error."""
        free = self.free_responses(actuator)
        x = self._trace(actuator, 1)[:, 0]
        r, coef = self._residual(x, self.idx, free)
        names = MODELS[actuator.name][1]
        rms = float(np.sqrt(np.mean(r * r))) if np.all(np.isfinite(r)) else math.inf
        return TransferFit(
            actuator, dict.fromkeys(names, 0.0), np.zeros((len(names), len(names))), float(coef[0]), float(coef[1]),
            rms, rms, x + coef[0] + coef[1] * self.tc + sum(c * f[:, 0] for c, f in zip(coef[2:], free)), coef[2:],
        )  # fmt: skip

    def identify(self, name: str) -> TransferFit:
        """Model ``name`` fitted on all compared samples, with its held-out error and uncertainties."""
        values, res = self.fit(name)
        held = []
        for train, test in (self.halves, self.halves[::-1]):
            # Each half starts from the full fit's optimum: the basin is found once.
            half, _ = self.fit(name, train, [values])
            actuator = Actuator.from_values(name, half)
            # Offset, drift and the initial state are no dynamics: refitted on the held-out samples.
            r, _ = self._residual(self._trace(actuator, 1)[:, 0], test, self.free_responses(actuator))
            held.append(r)
        actuator = Actuator.from_values(name, values)
        free = self.free_responses(actuator)
        x = self._trace(actuator, 1)[:, 0]
        r, coef = self._residual(x, self.idx, free)
        offset, drift, initial = float(coef[0]), float(coef[1]), coef[2:]
        cov = _covariance(res, name, values)
        names = MODELS[name][1]
        stderr = {k: float(math.sqrt(max(cov[i, i], 0.0))) for i, k in enumerate(names)}
        held_r = np.concatenate(held)
        return TransferFit(
            actuator,
            stderr,
            cov,
            offset,
            drift,
            float(np.sqrt(np.mean(r * r))),
            float(np.sqrt(np.mean(held_r * held_r))) if np.all(np.isfinite(held_r)) else math.inf,
            x + offset + drift * self.tc + sum(c * f[:, 0] for c, f in zip(initial, free)),
            initial,
        )


def _covariance(res, name: str, values: dict[str, float]) -> np.ndarray:
    """Parameter covariance from the fit's Jacobian (log-rate mapped back), inflated for autocorrelation."""
    jac, r = res.jac, res.fun
    n, k = jac.shape
    s2 = float(r @ r) / max(n - k - 2, 1)  # offset and drift were fitted too
    rho = float(np.clip(np.corrcoef(r[:-1], r[1:])[0, 1], 0.0, 0.999)) if n > 3 and np.std(r) > 0 else 0.0
    cov = np.linalg.pinv(jac.T @ jac) * s2 * (1.0 + rho) / (1.0 - rho)
    names = MODELS[name][1]
    if "rate" in names:  # d rate = rate d log(rate)
        i = names.index("rate")
        cov[i, :] *= values["rate"]
        cov[:, i] *= values["rate"]
    return cov


def lag_of(command: np.ndarray, measured: np.ndarray, dt: float, max_lag: float = 0.2) -> float:
    """Lag of ``measured`` behind ``command`` [s]: the peak of their cross-correlation up to ``max_lag``
    (and a quarter of the record), refined by a parabola."""
    x = measured - np.mean(measured)
    c = command - np.mean(command)
    k = max(2, min(int(max_lag / dt), len(x) // 4))
    n = len(x)
    corr = np.array([float(x[j:] @ c[: n - j]) for j in range(k + 1)])
    j = int(np.clip(np.argmax(corr), 1, k - 1))
    den = corr[j - 1] - 2.0 * corr[j] + corr[j + 1]
    shift = 0.5 * (corr[j - 1] - corr[j + 1]) / den if den < 0 else 0.0
    return float(max((j + shift) * dt, 0.0))


@dataclass
class TransferIdentification:
    """Every transfer model fitted to one record, the selected one and the nominal actuator it is compared with.

    Attributes
    ----------
    fits : dict
        :class:`TransferFit` by model name.
    selected : str
        The simplest model whose held-out mean square is within :data:`SELECT_MARGIN` of the best.
    nominal : Actuator
        The actuator the record's metadata describes.
    frequency : float
        Forcing frequency the effective delay is evaluated at [Hz].
    noise : float
        LVDT noise standard deviation [m] (third differences).
    """

    fits: dict[str, TransferFit]
    selected: str
    nominal: Actuator
    frequency: float
    noise: float
    problem: TransferProblem = field(repr=False)
    described: TransferFit | None = field(repr=False, default=None)

    @property
    def best(self) -> TransferFit:
        return self.fits[self.selected]

    @property
    def motion_fit(self) -> TransferFit:
        """The fit whose motion drives the physical substructure's replay: the better servo model.

        At a forcing far below the servo's bandwidth every model reproduces the LVDT to its
        noise, and parsimony selects the pure delay for the verdict; but the platform's
        acceleration (what the pendulum and the load cell feel) keeps the servo's limited
        bandwidth, which a delayed copy of a jittery command (a forward predictor's) does not
        have: its tick-to-tick accelerations reached the load cell as 50 % force errors. The
        selected model drives it only where the second-order one predicts the LVDT worse.

        A command declared held (``daq.command``) makes the acceleration jump by ws^2 x the
        command's step at each switch, which a load cell sampled at the tick reads in full; the
        LVDT cannot tell the servo's shape at the forcing, so the servo the metadata describes
        (:attr:`described`) drives the replay where it predicts the LVDT as well as the selected model.
        """
        if self.described is not None:
            if self.described.error_held_out**2 <= (1.0 + SELECT_MARGIN) * self.best.error_held_out**2:
                return self.described
        servo = min((self.fits["second_order"], self.fits["first_order"]), key=lambda f: f.error_held_out)
        if servo.error_held_out**2 <= (1.0 + SELECT_MARGIN) * self.best.error_held_out**2:
            return servo
        return self.best

    def effective_delay(self) -> tuple[float, float]:
        return self.best.effective_delay(self.frequency)

    def compare_derivatives(self, measured: dict[str, np.ndarray]) -> dict[str, dict[str, float]]:
        """The motion that drives the specimen's replay (:attr:`motion_fit`) against a measured platform
        velocity ``ydot`` [m/s] and acceleration ``yddot`` [m/s^2], where the record has them.

        Per column, on the compared samples: the rms difference, the column's noise (third
        differences), their mean-square ratio and the correlation of the difference with the model.
        The LVDT sees displacement only; a servo's acceleration, which the pendulum and the load cell
        feel, is the model's guess until an accelerometer says otherwise (a command held over each
        tick into a fast servo jerks the platform at every tick, which no smooth model has).
        """
        fit = self.motion_fit
        motion = self.problem.motion(fit.actuator, 1, fit.initial)
        idx = self.problem.idx
        out = {}
        for column, k, extra in (("ydot", 1, fit.drift), ("yddot", 2, 0.0)):
            if column not in measured:
                continue
            model = motion[idx, k] + extra
            diff = model - measured[column][idx]
            noise = noise_std(measured[column])
            out[column] = {
                "rms_difference": float(np.sqrt(np.mean(diff * diff))),
                "noise": noise,
                "ratio_to_noise": float(np.mean(diff * diff) / noise**2) if noise > 0 else math.inf,
                "correlation_with_model": float(np.corrcoef(diff, model)[0, 1]) if np.std(diff) > 0 else 0.0,
            }
        return out

    def to_json(self) -> dict[str, Any]:
        f = self.frequency
        delay, delay_sigma = self.effective_delay()
        amplitude, amplitude_sigma = self.best.amplitude(f)
        return {
            "selected": self.selected,
            "frequency": f,
            "effective_delay": delay,
            "effective_delay_uncertainty": delay_sigma,
            "amplitude_ratio": amplitude,
            "amplitude_ratio_uncertainty": amplitude_sigma,
            "nominal": self.nominal.to_dict(),
            "nominal_effective_delay": self.nominal.effective_delay(f),
            "nominal_amplitude_ratio": self.nominal.amplitude(f),
            "lvdt_noise": self.noise,
            "models": {name: fit.to_json() for name, fit in self.fits.items()},
        }


def identify_transfer(
    t: np.ndarray, command: np.ndarray, measured: np.ndarray, frequency: float, nominal: Actuator, shape: str = "smooth"
) -> TransferIdentification:
    """Fit every model of :data:`MODELS` to one record and select one by held-out error (module docstring).

    Parameters
    ----------
    t, command, measured : ndarray
        Sample times [s], command ``y_cmd`` [m] and measured platform displacement ``y`` [m].
    frequency : float
        Forcing frequency [Hz] at which the effective delay is reported.
    nominal : Actuator
        The actuator the record's metadata describes.
    shape : str
        How the actuator received the command (:class:`TransferProblem`).
    """
    if np.ptp(command) == 0.0:
        raise ConfigError("the command y_cmd is constant: the actuator cannot be identified from it")
    reach = float(np.max(np.abs(command)))
    if reach > MAX_STROKE:
        raise ConfigError(
            f"the command y_cmd reaches {reach:.3g} m, beyond any actuator stroke of this rig ({MAX_STROKE:g} m): "
            'check its units (declare them in the metadata\'s columns, e.g. {"y_cmd": {"unit": "mm"}, '
            '"y": {"unit": "mm"}})'
        )
    ratio = float(np.std(measured) / np.std(command))
    if not 0.2 <= ratio <= 5.0:
        raise ConfigError(
            f"the measured displacement y moves {ratio:.3g} x as much as the command y_cmd: check their units "
            '(declare them in the metadata\'s columns, e.g. {"y_cmd": {"unit": "mm"}})'
        )
    problem = TransferProblem(t, command, measured, shape)
    fits = {name: problem.identify(name) for name in MODELS}
    best_ms = min(f.error_held_out**2 for f in fits.values())
    selected = next(name for name in MODELS if fits[name].error_held_out ** 2 <= (1.0 + SELECT_MARGIN) * best_ms)
    described = problem.evaluate(nominal) if shape == "held" and nominal.order else None
    return TransferIdentification(fits, selected, nominal, float(frequency), problem.noise, problem, described)


def dominant_frequency(x: np.ndarray, dt: float) -> float:
    """Frequency of the largest spectral peak of ``x`` [Hz] (mean removed, Hann window)."""
    x = (x - np.mean(x)) * np.hanning(len(x))
    spectrum = np.abs(np.fft.rfft(x))
    spectrum[0] = 0.0
    return float(np.fft.rfftfreq(len(x), dt)[int(np.argmax(spectrum))])
