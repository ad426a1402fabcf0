"""Identify the oscillator's linear dynamics from the record's frequency content, before any replay.

The replays' least squares start from the nominal model. Where the record's
response to the oscillator's stiffness K, mass M and damping C is far from
linear in them (a resonance between the nominal and the true natural
frequency, a start-up transient at the model's own natural frequency) the
fit of K can stop in another basin, and a look-alike cause that bends the
response more freely then wins. This stage reads the oscillator's dynamics
off the record instead (the first stage of the diagnosis: identify, replay,
fit, judge, report):

* the **forcing content**: the tones of the external force (frequencies and
  amplitudes, from its spectrum's peaks) or, when the tones do not hold the
  force's power, a swept band;
* the **response at each tone**: the complex amplitudes of the displacement
  and of the net force at the tone, by least squares on the record, and the
  receptance ``Y/F``; a **transient** (a record started from rest) is fitted
  with them as a decaying oscillation ``exp(-s t) (a cos w t + b sin w t)``,
  whose natural frequency ``sqrt(s^2 + w^2)`` and damping ratio are the
  oscillator's own;
* the **equation of motion** ``M_o y'' + C y' + K y + k3 y^3 = F_net`` at
  those frequencies, fitted by linear least squares: at each component of
  complex frequency p (``i w_k`` of tone k, ``-s + i w`` of a transient),
  ``F_p = (K + M_o p^2 + C p) Y_p``, with the cubic's describing-function
  stiffness ``3/4 k3 (A_k^2 + 2 sum_j A_j^2)`` at tone k (j over the other
  tones); the transient's balance holds with what drives it over the
  transient (in a closed loop the load cell feeds the transient back, so its
  frequency is not the numerical model's own); a sweep is fitted
  bin by bin over its band of the Hann-windowed spectra (derivatives exact
  there, ``(i w)^n``, and the cubic as the spectrum of ``y^3``). Each
  parameter is also fitted alone with the others nominal: the start of its
  candidate's fit.

What drives the oscillator, by replay kind: a forced record's ``Fe`` less the
pendulum's reaction of Eq. (1), ``m l (theta'' sin theta + theta'^2 cos theta)
= m l d^2(-cos theta)/dt^2`` (nominal m, l; ``M_o = M + m``), taken at each
frequency as ``m l w^2`` times ``cos theta``'s amplitude there (no derivative
of a quantised angle is estimated); a substructured record's numerical model
(its own output ``y_star``, or the command ``y_cmd``) the force it was given,
``Fe`` less the load cell's ``Fs`` or the fed-back ``F_fb`` (``M_o = M - M2``).

Whether the record can tell two look-alike causes apart is read off the same
equations: K and M are separable when the response holds more than one
frequency (two tones, a sweep, a tone and a transient); a single tone in
steady state shows only ``K - M_o w^2``. K and k3 are separable when the
amplitude changes across the record's frequencies (two tones of different
amplitudes, a sweep through a resonance); at one steady tone a cubic spring
is a constant stiffness ``3/4 k3 A^2``. The collinearity is the variance
inflation factor of the K column against the other one in the regression
(:data:`SEPARABLE_VIF`); besides the forcing, the frequencies include the
peaks of the net force (a swinging pendulum's reaction harmonics) where the
displacement responds above the LVDT's noise, looked for with the forcing
tones taken out (a tone between the spectrum's bins has sidelobes, no peaks
of their own) and above the quasi-static band (:data:`QUASI_STATIC_INERTIA`:
there the sensors' drift, not the oscillator). Where the record cannot
separate stiffness from mass the diagnosis ties them whatever the replays'
held-out blocks say (``judge.FORCED_TIES``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

#: A look-alike pair is separable in principle when the K column's variance inflation factor against its
#: partner's in the regression is below this: the columns are then not multiples of each other, because
#: the response holds a second frequency (a tone, a sweep, a transient, a driven peak above the noise).
#: One frequency alone makes them exact multiples: 1e12 (the factor's cap) on every one-tone record seen,
#: against 2.7e4-3.6e4 with a swinging pendulum's reaction harmonics, 1e3-3e3 with a start-up transient
#: near the tone and 10-300 with two tones. (Before the tones were taken out of the search for other
#: peaks and quasi-static ones dropped, a steady tone's window sidelobes and the sensors' drift gave
#: 1e5-1e8 on one tone: separable by the factor, not by the record.)
SEPARABLE_VIF = 1e8
#: A spectral peak of the external force is a tone when it holds this share of the largest peak.
TONE_SHARE = 0.05
#: The force is a sweep (not tones) when its tones hold less than this share of its power.
TONE_POWER_SHARE = 0.8
#: A sweep's band: the bins where the force's spectrum exceeds this share of its peak.
SWEEP_SHARE = 0.1
#: A peak of the net force away from the forcing tones counts as a frequency the oscillator responds at
#: when the displacement's spectrum there exceeds this multiple of the LVDT noise's spectral level.
DRIVEN_SNR = 10.0
#: A driven peak counts only where the inertia's share of the nominal dynamic stiffness, ``M_o w^2 / K``, is at
#: least this (above 0.22 of the natural frequency, 0.47 Hz on the paper's rig). Below it the bin tells the
#: static stiffness alone, read off quasi-static force and displacement, where both sensors drift (a load
#: cell's 0.05 N, an LVDT's random walk): a drift in either reads as a stiffness, and on one steady tone a
#: peak at 0.02-0.15 Hz made stiffness and mass look separable (variance inflation 2e5 instead of 1e12)
#: while the replays' choice between them followed the drift.
QUASI_STATIC_INERTIA = 0.05
#: A transient is fitted when the displacement's departure from its steady tones over the first
#: TRANSIENT_WINDOW seconds exceeds this multiple of its departure over the record's second half.
TRANSIENT_RATIO = 5.0
TRANSIENT_WINDOW = 2.0
#: The look-alike pairs of the oscillator whose separability this stage judges.
PAIRS = {
    frozenset({"oscillator_stiffness", "oscillator_mass"}),
    frozenset({"oscillator_stiffness", "spring_hardening"}),
}


@dataclass(frozen=True)
class Tone:
    """One forcing tone and the displacement's steady response at it.

    Attributes
    ----------
    frequency : float
        [Hz].
    force, displacement : float
        Amplitudes [N], [m].
    receptance : complex
        Displacement over force at the tone [m/N].
    """

    frequency: float
    force: float
    displacement: float
    receptance: complex


@dataclass
class OscillatorIdentification:
    """The oscillator's dynamics as read off one record (module docstring).

    Attributes
    ----------
    tones : list of Tone
        The force's tones (empty for a sweep).
    sweep : tuple of float or None
        The swept band [Hz] when the force is no sum of tones.
    transient : dict or None
        ``frequency`` [Hz], ``damping_ratio`` [-], ``amplitude`` [m] of a decaying oscillation at the
        record's start.
    estimates, stderr : dict
        Vocabulary parameters ``K`` [N/m], ``M`` [kg], ``C`` [kg/s] fitted together and ``k3``
        [N/m^3] with them, from the equation error, and their one-sigma uncertainties (from the
        residual's spread over the excited bins).
    alone : dict
        Each of ``K``, ``M``, ``C``, ``k3`` fitted alone, the others nominal: the start of that
        parameter's candidate.
    inflation : dict
        Variance inflation factor of the K column against the M column (``"M"``) and against the
        cubic one (``"k3"``) in the joint regression.
    amplitude_range : tuple of float
        5th and 95th percentiles of the displacement's envelope [m].
    driven : list of float
        Frequencies [Hz] besides the forcing where the net force drives a response above the noise
        (a swinging pendulum's reaction harmonics).
    """

    tones: list[Tone]
    sweep: tuple[float, float] | None
    transient: dict[str, float] | None
    estimates: dict[str, float]
    stderr: dict[str, float]
    alone: dict[str, float]
    inflation: dict[str, float]
    amplitude_range: tuple[float, float]
    driven: list[float]

    def separates(self, cause_a: str, cause_b: str) -> tuple[bool, str] | None:
        """Whether the record can tell ``cause_a`` from ``cause_b`` and why (None: not a pair judged here)."""
        pair = frozenset({cause_a, cause_b})
        if pair not in PAIRS:
            return None
        if "oscillator_mass" in pair:
            vif = self.inflation["M"]
            seen = self.content()
            if vif < SEPARABLE_VIF:
                return True, f"the displacement holds {seen}: K and M act differently at different frequencies"
            return False, (
                f"the displacement holds {seen}, in steady state: only K - M omega^2 is seen there "
                f"(stiffness and inertia columns collinear, variance inflation {vif:.3g})"
            )
        vif = self.inflation["k3"]
        low, high = self.amplitude_range
        if vif < SEPARABLE_VIF:
            return True, (
                f"the displacement's envelope spans {1e3 * low:.3g} to {1e3 * high:.3g} mm: a cubic spring's stiffness "
                "changes with amplitude and adds harmonics, a linear one does not"
            )
        return False, (
            f"the displacement's envelope stays within {1e3 * low:.3g} to {1e3 * high:.3g} mm: a cubic spring acts "
            f"as a constant stiffness there (linear and cubic columns collinear, variance inflation {vif:.3g})"
        )

    def content(self) -> str:
        """The frequencies the record's displacement holds, in words."""
        parts = []
        if self.sweep is not None:
            parts.append(f"a sweep over {self.sweep[0]:.3g}-{self.sweep[1]:.3g} Hz")
        elif self.tones:
            freqs = ", ".join(f"{t.frequency:.3g}" for t in self.tones)
            parts.append(f"{len(self.tones)} tone{'s' if len(self.tones) > 1 else ''} ({freqs} Hz)")
        if self.driven:
            freqs = ", ".join(f"{f:.3g}" for f in self.driven)
            parts.append(f"a response driven by the pendulum or load cell at {freqs} Hz")
        if self.transient is not None:
            parts.append(f"a transient at {self.transient['frequency']:.3g} Hz")
        return " and ".join(parts) or "no forcing tone"

    def to_json(self) -> dict[str, Any]:
        return {
            "tones": [
                {"frequency": t.frequency, "force": t.force, "displacement": t.displacement,
                 "receptance": [t.receptance.real, t.receptance.imag]}
                for t in self.tones
            ],
            "sweep": list(self.sweep) if self.sweep else None,
            "transient": self.transient,
            "estimates": self.estimates,
            "stderr": self.stderr,
            "alone": self.alone,
            "variance_inflation": self.inflation,
            "amplitude_range": list(self.amplitude_range),
            "driven": self.driven,
        }  # fmt: skip


@dataclass
class _Signals:
    """What the oscillator of a replay sees, from sample ``start`` on (:func:`oscillator_signals`)."""

    t: np.ndarray  # [s]
    y: np.ndarray  # displacement [m]
    external: np.ndarray  # the external force alone [N]
    driving: list[tuple[np.ndarray, float, int]]  # net force: sum of factor x p^power x signal (p: complex frequency)
    mass_offset: float  # vocabulary M = M_o - mass_offset [kg]
    start: int
    noise: float  # the displacement's noise [m]: its sensor's, or the numerical output's convention floor


def oscillator_signals(replay: Any) -> _Signals | None:
    """The oscillator a replay holds and what drives it (module docstring), or None for kinds without one.

    The net force is ``sum(factor_i * p^power_i * signal_i)`` at the complex frequency p (``i w`` of a
    tone): ``(Fe, gain, 0)`` and, on a forced record, less the pendulum's reaction, ``(cos theta, m l, 2)``
    (the reaction is ``m l d^2(-cos theta)/dt^2``).
    """
    record, nominal = replay.record, replay.nominal
    if replay.kind == "forced":
        t = replay.t
        theta = record.channel("theta")
        driving = [(record.channel("Fe"), nominal["gain"], 0), (np.cos(theta), nominal["m"] * nominal["l"], 2)]
        return _Signals(t, record.channel("y"), record.channel("Fe"), driving, nominal["m"], 0, replay.noise["y"])
    if replay.kind in ("numerical", "substructured") and "Fs" in record.data:
        start = replay.start
        feedback = record.channel("F_fb" if "F_fb" in record.data else "Fs")[start:]
        fe = record.channel("Fe")[start:]
        output = getattr(replay, "output", "y_cmd")
        driving = [(fe, nominal["gain"], 0), (feedback, -1.0, 0)]
        noise = replay.noise.get(output, 0.0)
        return _Signals(replay.t[start:], record.channel(output)[start:], fe, driving, -nominal["M2"], start, noise)
    return None


def identify_oscillator(replay: Any) -> OscillatorIdentification | None:
    """The oscillator's dynamics read off ``replay``'s record (module docstring); None for kinds without one."""
    sig = oscillator_signals(replay)
    if sig is None:
        return None
    nominal = replay.nominal
    t, y = sig.t - sig.t[0], sig.y
    freqs, sweep = _forcing_content(sig.external, replay.dt)
    transient = None
    # Below this the record's content is quasi-static (:data:`QUASI_STATIC_INERTIA`): the sensors' drift.
    natural = math.sqrt(nominal["K"] / (nominal["M"] + sig.mass_offset)) / (2 * math.pi)
    lowest = math.sqrt(QUASI_STATIC_INERTIA) * natural
    if sweep is None:
        forcing = len(freqs)
        # Other frequencies are looked for with the forcing tones taken out of every signal (least squares
        # sines): the window's sidelobes of a tone that does not fall on a bin are no peaks of their own.
        tone_basis = _sines(t, freqs)

        def detoned(x: np.ndarray) -> np.ndarray:
            return x - tone_basis @ np.linalg.lstsq(tone_basis, x, rcond=None)[0]

        net = sum(factor * (2j * math.pi * np.fft.rfftfreq(len(y), replay.dt)) ** power * _spectrum(detoned(signal))
                  for signal, factor, power in sig.driving)  # fmt: skip
        freqs = freqs + _driven_peaks(net, _spectrum(detoned(y)), freqs, replay.dt, sig.noise, lowest)
        basis, transient = _response_basis(t, y, freqs, sig.noise)
        # Complex frequencies p of the basis's components: i w at the tones, -s + i w of a transient.
        p = 2j * math.pi * np.array(freqs, dtype=complex)
        if transient is not None:
            natural, zeta = 2 * math.pi * transient["frequency"], transient["damping_ratio"]
            p = np.append(p, complex(-zeta * natural, natural * math.sqrt(1.0 - zeta * zeta)))
        response = _amplitudes(basis, y, len(p))
        force = sum(factor * p**power * _amplitudes(basis, signal, len(p)) for signal, factor, power in sig.driving)
        external = np.abs(_amplitudes(basis, sig.external, len(freqs)))
        tones = [
            Tone(f, float(fa), float(abs(ya)), complex(ya / fy))
            for f, fa, ya, fy in zip(freqs[:forcing], external, response, force)
        ]  # fmt: skip
        amp2 = np.abs(response[: len(freqs)]) ** 2
        # The cubic's describing-function stiffness at each tone: 3/4 k3 (A_k^2 + 2 sum of the others' A_j^2);
        # a decaying transient's amplitude sweeps down, which the tones' balance does not describe: none there.
        cubic = np.zeros(len(p), dtype=complex)
        cubic[: len(freqs)] = 0.75 * (2.0 * amp2.sum() - amp2) * response[: len(freqs)]
        columns = {"K": response, "M": p**2 * response, "C": p * response, "k3": cubic}
        target = force
    else:
        tones = []
        spectrum_f = _spectrum(sig.external)
        bins = np.fft.rfftfreq(len(y), replay.dt)
        band = np.abs(spectrum_f) >= SWEEP_SHARE * np.max(np.abs(spectrum_f[1:]))
        band[0] = False
        if np.any(band & (bins >= lowest)):
            band &= bins >= lowest  # a drifting load cell's quasi-static bins are no part of the sweep
            sweep = (float(bins[band].min()), float(bins[band].max()))
        omega = 2 * math.pi * bins[band]
        response = _spectrum(y)[band]
        target = sum(factor * (1j * omega) ** power * _spectrum(signal)[band] for signal, factor, power in sig.driving)
        columns = {
            "K": response, "M": -(omega**2) * response, "C": 1j * omega * response, "k3": _spectrum(y**3)[band],
        }  # fmt: skip
    linear, linear_sigma = _regress(columns, target, ("M", "C", "K"))
    full, full_sigma = _regress(columns, target, ("M", "C", "K", "k3"))
    estimates = {"K": linear["K"], "M": linear["M"] - sig.mass_offset, "C": linear["C"], "k3": full["k3"]}
    stderr = {"K": linear_sigma["K"], "M": linear_sigma["M"], "C": linear_sigma["C"], "k3": full_sigma["k3"]}
    inflation = {"M": _inflation(columns, "K", ("M",)), "k3": _inflation(columns, "K", ("k3",))}
    # Each parameter alone, the others nominal: where the record holds one tone, K and M cannot be had
    # together, but each one's value given the other is what its candidate's fit should start from.
    base = {"K": nominal["K"], "M": nominal["M"] + sig.mass_offset, "C": nominal["C"], "k3": nominal["k3"]}
    alone = {}
    for name in ("K", "M", "C", "k3"):
        rest = target - sum(base[k] * columns[k] for k in columns if k != name)
        value = _regress({name: columns[name]}, rest, (name,))[0][name]
        alone[name] = value - sig.mass_offset if name == "M" else value
    envelope = _envelope(y)
    driven = freqs[len(tones) :] if sweep is None else []
    return OscillatorIdentification(tones, sweep, transient, estimates, stderr, alone, inflation, envelope, driven)


def _spectrum(x: np.ndarray) -> np.ndarray:
    """Hann-windowed one-sided spectrum of ``x`` less its mean."""
    return np.fft.rfft((x - np.mean(x)) * np.hanning(len(x)))


def _envelope(y: np.ndarray) -> tuple[float, float]:
    """5th and 95th percentiles of the displacement's envelope [m]: half its range over a sliding 1/8 of the record."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    w = max(3, len(y) // 8)
    half_range = 0.5 * (maximum_filter1d(y, w) - minimum_filter1d(y, w))
    low, high = np.percentile(half_range[w // 2 : len(y) - w // 2], [5.0, 95.0])
    return float(low), float(high)


def _regress(columns: dict[str, np.ndarray], target: np.ndarray, names: tuple[str, ...]):
    """Least squares of the complex ``target`` on ``columns[names]`` with real coefficients: values and
    one-sigma uncertainties (from the residual's spread)."""
    x = np.stack([columns[k] for k in names], axis=1)
    x = np.concatenate([x.real, x.imag])
    b = np.concatenate([target.real, target.imag])
    scale = np.maximum(np.sqrt(np.mean(x * x, axis=0)), 1e-300)
    coef, *_ = np.linalg.lstsq(x / scale, b, rcond=None)
    r = b - (x / scale) @ coef
    n, k = x.shape
    s2 = float(r @ r) / max(n - k, 1)
    cov = np.linalg.pinv((x / scale).T @ (x / scale)) * s2
    values = {name: float(c / s) for name, c, s in zip(names, coef, scale)}
    sigma = {name: float(math.sqrt(max(cov[i, i], 0.0)) / scale[i]) for i, name in enumerate(names)}
    return values, sigma


def _inflation(columns: dict[str, np.ndarray], name: str, others: tuple[str, ...]) -> float:
    """Variance inflation factor of column ``name`` against ``others``: ``1 / (1 - R^2)`` of its
    (real-coefficient) regression on them."""
    x = np.stack([columns[k] for k in others], axis=1)
    x = np.concatenate([x.real, x.imag])
    y = np.concatenate([columns[name].real, columns[name].imag])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    r = y - x @ coef
    share = float(r @ r) / max(float(y @ y), 1e-300)
    return 1.0 / max(share, 1e-12)


def _forcing_content(force: np.ndarray, dt: float) -> tuple[list[float], tuple[float, float] | None]:
    """The external force's tone frequencies [Hz] and None, or no tones and the band of a sweep [Hz].

    Tones are the Hann-windowed spectrum's peaks above :data:`TONE_SHARE` of the largest, refined by a
    parabola through the log magnitudes. When sines at them hold less than :data:`TONE_POWER_SHARE`
    of the force's power, the force is a sweep, and its band is where the spectrum exceeds
    :data:`SWEEP_SHARE` of its peak.
    """
    spectrum = np.abs(_spectrum(force))
    freqs = np.fft.rfftfreq(len(force), dt)
    spectrum[0] = 0.0
    peak = float(spectrum.max())
    if peak <= 0:
        return [], None
    found = []
    for i in range(1, len(spectrum) - 1):
        if spectrum[i] >= TONE_SHARE * peak and spectrum[i] >= spectrum[i - 1] and spectrum[i] > spectrum[i + 1]:
            found.append(float((i + _peak_shift(spectrum[i - 1 : i + 2])) * (freqs[1] - freqs[0])))
    # A peak's refinement never yields a frequency the basis cannot hold (no NaN reaches the least squares).
    found = [f for f in found if math.isfinite(f) and f > 0.0]
    t = np.arange(len(force)) * dt
    basis = _sines(t, found)
    x = force - np.mean(force)
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    share = 1.0 - float(np.var(x - basis @ coef)) / max(float(np.var(x)), 1e-300)
    if share < TONE_POWER_SHARE:
        band = freqs[spectrum >= SWEEP_SHARE * peak]
        return [], (float(band.min()), float(band.max()))
    return found, None


def _driven_peaks(
    net: np.ndarray, response: np.ndarray, tones: list[float], dt: float, noise: float, lowest: float = 0.0
) -> list[float]:
    """Frequencies [Hz] other than the forcing tones where the net force peaks and drives a displacement
    :data:`DRIVEN_SNR` times above the LVDT noise's level in the spectrum: the pendulum's reaction at the
    harmonics of its swing (or a load cell's content), a second frequency the oscillator responds at.
    Quasi-static peaks, below ``lowest`` [Hz] (:data:`QUASI_STATIC_INERTIA`), are the sensors' drift as
    much as a response: not counted."""
    n = 2 * (len(net) - 1)
    df = 1.0 / (n * dt)
    floor = DRIVEN_SNR * noise * math.sqrt(float(np.sum(np.hanning(n) ** 2)))
    magnitude = np.abs(net)
    near_tone = np.zeros(len(net), dtype=bool)
    near_tone[0] = True
    for f in tones:
        k = int(round(f / df))
        near_tone[max(k - 3, 0) : k + 4] = True
    found = []
    if not floor > 0:  # a displacement without noise of its own: no level to stand out from
        return found
    for i in range(1, len(net) - 1):
        if near_tone[i] or i * df < lowest:
            continue
        if not (magnitude[i] >= magnitude[i - 1] and magnitude[i] > magnitude[i + 1]):
            continue
        if abs(response[i]) >= floor:
            found.append(float((i + _peak_shift(magnitude[i - 1 : i + 2])) * df))
    return [f for f in found if math.isfinite(f) and f > 0.0]


def _peak_shift(three: np.ndarray) -> float:
    """Offset [bins] of a spectral peak from its bin ``i``, by a parabola through the log magnitudes at
    ``i - 1, i, i + 1``; 0 where a neighbour is zero (the zeroed mean's bin next to a peak at bin 1), a
    magnitude is not finite, or the parabola does not open downwards. Within half a bin."""
    if not (np.all(np.isfinite(three)) and np.all(three > 0.0)):
        return 0.0
    a, b, c = np.log(three)
    curvature = a - 2.0 * b + c
    if not curvature < 0.0:
        return 0.0
    shift = 0.5 * (a - c) / curvature
    return float(np.clip(shift, -0.5, 0.5)) if math.isfinite(shift) else 0.0


def _sines(t: np.ndarray, freqs: list[float]) -> np.ndarray:
    """Columns ``cos(w t), sin(w t)`` per frequency, and a constant."""
    cols = [np.ones_like(t)]
    for f in freqs:
        cols += [np.cos(2 * math.pi * f * t), np.sin(2 * math.pi * f * t)]
    return np.stack(cols, axis=1)


def _amplitudes(basis: np.ndarray, x: np.ndarray, n_tones: int) -> np.ndarray:
    """Complex amplitudes ``X_k`` (``x = Re(X_k exp(i w_k t))``) of the first ``n_tones`` tones of ``basis`` in ``x``."""
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    cos_sin = coef[1 : 1 + 2 * n_tones].reshape(-1, 2)
    return cos_sin[:, 0] - 1j * cos_sin[:, 1]


def _response_basis(
    t: np.ndarray, y: np.ndarray, freqs: list[float], noise: float
) -> tuple[np.ndarray, dict[str, float] | None]:
    """The least-squares basis of the displacement: the tones' sines and a constant, and a decaying
    oscillation when the record starts with a transient (module docstring), with the transient's
    natural frequency [Hz], damping ratio [-] and initial amplitude [m]."""
    tones = _sines(t, freqs)
    late = t >= t[-1] / 2
    early = t < TRANSIENT_WINDOW
    coef, *_ = np.linalg.lstsq(tones[late], y[late], rcond=None)
    departure = y - tones @ coef
    rms_early = float(np.sqrt(np.mean(departure[early] ** 2))) if early.sum() > 20 else 0.0
    rms_late = float(np.sqrt(np.mean(departure[late] ** 2)))
    if rms_early < TRANSIENT_RATIO * max(rms_late, noise):
        return tones, None
    # The transient's frequency starts from the departure's spectral peak over the early part.
    spectrum = np.abs(np.fft.rfft(departure[early] * np.hanning(early.sum()), 8 * early.sum()))
    spectrum[0] = 0.0
    omega0 = 2 * math.pi * np.fft.rfftfreq(8 * early.sum(), t[1] - t[0])[int(np.argmax(spectrum))]

    def design(u: np.ndarray) -> np.ndarray:
        decay, omega = u
        envelope = np.exp(-decay * t)
        return np.concatenate([tones, np.stack([envelope * np.cos(omega * t), envelope * np.sin(omega * t)], 1)], 1)

    def residual(u: np.ndarray) -> np.ndarray:
        d = design(u)
        return d @ np.linalg.lstsq(d, y, rcond=None)[0] - y

    fit = least_squares(residual, [1.0, max(omega0, 0.2)], bounds=([0.0, 0.1], [1e3, 1e4]), x_scale=[1.0, omega0])
    decay, omega = fit.x
    d = design(fit.x)
    coef = np.linalg.lstsq(d, y, rcond=None)[0]
    natural = math.hypot(decay, omega)
    return d, {
        "frequency": natural / (2 * math.pi),
        "damping_ratio": decay / natural,
        "amplitude": float(math.hypot(coef[-2], coef[-1])),
    }
