"""Seeded measured-like records from a truth model (``pendsweep synth``).

The truth is the nominal model with any vocabulary effects applied. It is
integrated ``oversample`` times finer than the record's sampling, with the
exact sinusoidal force, and then measured with the sensors of the
substructured backend (one set of assumptions for the project): the encoder
quantises theta in steps of :data:`ENCODER_RESOLUTION` (Table III), the LVDT
has 10 um steps and 20 um rms noise, the load cell 0.1 N rms noise.
The record's metadata carries the *nominal* model, so the effect is hidden.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ...backends.substructured import SubstructuredBackend as _Rig
from ...errors import ConfigError
from ...kernels import driven_trace, pendulum_trace, substructured_replay
from ...model.params import ModelParams
from ..records import Record
from .effects import EFFECTS, nominal_values, split_values


@dataclass(frozen=True)
class Sensors:
    """Quantisation steps and rms noise of the measured channels (SI units)."""

    theta_step: float = _Rig.encoder_resolution
    y_step: float = _Rig.lvdt_resolution
    y_noise: float = _Rig.lvdt_noise
    force_step: float = 0.0
    force_noise: float = _Rig.force_noise


def _measure(x: np.ndarray, step: float, noise: float, rng: np.random.Generator) -> np.ndarray:
    if noise > 0:
        x = x + rng.normal(0.0, noise, x.shape)
    return step * np.round(x / step) if step > 0 else x


def synthesize(
    kind: str,
    nominal: ModelParams,
    effects: dict[str, float] | None = None,
    duration: float = 20.0,
    rate: float = 500.0,
    seed: int = 0,
    theta_init: float = 1.0,
    thetadot_init: float = 0.0,
    transient: float = 30.0,
    oversample: int = 4,
    sensors: Sensors = Sensors(),
    tone2: tuple[float, float] | None = None,
) -> Record:
    """A record of ``kind`` whose truth is ``nominal`` plus ``effects``.

    Parameters
    ----------
    kind : {"free_decay", "forced", "substructured"}
    nominal : ModelParams
        The model written to the record's metadata (the user's belief).
    effects : dict
        ``{cause: value}``: each cause's parameter takes ``value`` in the truth
        (in the parameter's unit, see :data:`EFFECTS`).
    duration, rate : float
        Record length [s] and sample rate [Hz].
    seed : int
        Seed of the sensor noise.
    theta_init, thetadot_init : float
        Initial pendulum state [rad], [rad/s] (at release for free decays, at
        the start of the transient for forced records, with y = ydot = 0).
    transient : float
        Forced records: seconds simulated before recording starts.
    oversample : int
        Truth integration steps per sample (rig substeps per controller tick
        for substructured records, whose controller runs at the sample rate).
    sensors : Sensors
    tone2 : (float, float), optional
        A second force tone ``(amplitude [N], frequency [Hz])`` added to
        ``alpha sin(2 pi fe t)``. A single steady tone cannot separate the
        oscillator's K from M (only ``K - M omega_e^2`` is seen); two tones can.
    """
    if kind not in ("free_decay", "forced", "substructured"):
        raise ConfigError(f"synth kind {kind!r}; choose free_decay, forced or substructured")
    for name, value in (("duration", duration), ("rate", rate)):
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f"{name} = {value!r} must be positive and finite")
    n = int(round(duration * rate)) + 1
    if n < 50:
        raise ConfigError(f"duration x rate gives {n} samples; a record needs at least 50")
    truth = nominal_values(nominal)
    for cause, value in (effects or {}).items():
        if cause not in EFFECTS:
            raise ConfigError(f"unknown cause {cause!r}; the vocabulary is: {', '.join(EFFECTS)}")
        eff = EFFECTS[cause]
        if kind not in eff.kinds:
            raise ConfigError(f"cause {cause!r} does not apply to kind {kind!r}")
        truth[eff.param] = float(value)
    model, chain = split_values(truth)
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate
    h = dt / oversample
    p = model.kernel_array()
    t = np.arange(n) * dt
    if kind == "free_decay":
        fine = np.empty(((n - 1) * oversample + 1, 2))
        pendulum_trace(np.array([theta_init, thetadot_init]), p, h, 1, fine)
        theta = fine[::oversample, 0]
        data = pd.DataFrame({"t": t, "theta": _measure(theta + chain["theta_offset"], sensors.theta_step, 0.0, rng)})
        return Record(data, kind, nominal, name="synth")
    if kind == "substructured":
        return _substructured(
            model, chain, nominal, n, dt, rate, transient, theta_init, thetadot_init, oversample, sensors, rng, tone2
        )
    n_tr = int(round(transient * rate)) * oversample
    m = (n - 1) * oversample + 1 + n_tr
    tf = np.arange(m) * h
    tones = [(model.alpha, model.fe)] + ([tuple(map(float, tone2))] if tone2 else [])
    force = sum(a * np.sin(2.0 * math.pi * f * tf) for a, f in tones)
    half = sum(a * np.sin(2.0 * math.pi * f * (tf[:-1] + 0.5 * h)) for a, f in tones)
    fine = np.empty((m, 4))
    driven_trace(np.array([0.0, 0.0, theta_init, thetadot_init]), p, force, half, chain["gain"], h, fine)
    rec = fine[n_tr::oversample]
    data = pd.DataFrame(
        {
            "t": t,
            "theta": _measure(rec[:, 2] + chain["theta_offset"], sensors.theta_step, 0.0, rng),
            "y": _measure(rec[:, 0], sensors.y_step, sensors.y_noise, rng),
            "Fe": _measure(force[n_tr::oversample], sensors.force_step, sensors.force_noise, rng),
        }
    )
    return Record(data, kind, nominal, forcing={"alpha": model.alpha, "fe": model.fe}, name="synth")


def _substructured(
    model, chain, nominal, n, dt, rate, transient, theta_init, thetadot_init, oversample, sensors, rng, tone2
):
    """A substructuring test: the loop at the sample rate, the rig ``oversample`` times finer.

    The numerical model uses the nominal split ``M1 = M - M2``, ``C1 = C - C2``
    (code values); the platform has the truth's M2, C2. ``Fe`` and ``y_cmd``
    are controller signals and recorded exactly; x (as y), theta and Fs are
    measured. The loop feeds back the noise-free force.
    """
    n_tr = int(round(transient * rate))
    m = n + n_tr
    t = np.arange(m) * dt
    tones = [(model.alpha, model.fe)] + ([tuple(map(float, tone2))] if tone2 else [])
    force = sum(a * np.sin(2.0 * math.pi * f * t) for a, f in tones)
    half = sum(a * np.sin(2.0 * math.pi * f * (t[:-1] + 0.5 * dt)) for a, f in tones)
    M1 = model.M - nominal.M2 if "M" in _changed(model, nominal) else nominal.M1
    C1 = model.C - nominal.C2 if "C" in _changed(model, nominal) else nominal.C1
    cmd, cmdd = np.zeros(m), np.zeros(m)
    out = np.empty((m, 4))
    substructured_replay(
        np.array([0.0, 0.0, theta_init, thetadot_init]),
        model.kernel_array(),
        M1,
        C1,
        model.M2,
        model.C2,
        force,
        half,
        chain["gain"],
        chain["gain_Fs"],
        chain["tau"],
        dt,
        oversample,
        cmd,
        cmdd,
        0,
        out,
    )
    rec = out[n_tr:]
    data = pd.DataFrame(
        {
            "t": np.arange(n) * dt,
            "theta": _measure(rec[:, 1] + chain["theta_offset"], sensors.theta_step, 0.0, rng),
            "y": _measure(rec[:, 0], sensors.y_step, sensors.y_noise, rng),
            "Fe": force[n_tr:],
            "y_cmd": rec[:, 3],
            "Fs": _measure(rec[:, 2], sensors.force_step, sensors.force_noise, rng),
        }
    )
    return Record(data, "substructured", nominal, tau=0.0, forcing={"alpha": model.alpha, "fe": model.fe}, name="synth")


def _changed(model: ModelParams, nominal: ModelParams) -> set[str]:
    a, b = model.to_dict(), nominal.to_dict()
    return {k for k in a if a[k] != b[k]}
