"""The fixed vocabulary of candidate effects (model extensions).

Each cause has one parameter. Parameters that are :class:`ModelParams` fields
go into the extended-model params file; ``gain``, ``theta_offset``, ``tau`` and
``gain_Fs`` describe the measurement chain of one test and stay on the data
side (see ``docs/measured-data.md`` for how a sweep accounts for them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ...errors import ConfigError
from ...model.params import ModelParams


@dataclass(frozen=True)
class Effect:
    """One cause of the vocabulary.

    Attributes
    ----------
    cause, param : str
        Vocabulary name and the parameter it fits.
    kinds : tuple of str
        Record kinds on which the parameter is identifiable.
    scale : float
        Typical magnitude [param unit], used to scale the fit.
    lower, upper : float
        Physical bounds of the parameter.
    unit, meaning : str
    """

    cause: str
    param: str
    kinds: tuple[str, ...]
    scale: float
    lower: float
    upper: float
    unit: str
    meaning: str


_ALL = ("free_decay", "forced", "substructured", "physical")
_OSC = ("forced", "substructured", "numerical")
#: The physical substructure of a substructured test, replayed on its own (:mod:`.replay.parts`).
_RIG = ("substructured", "physical")
_INF = math.inf

EFFECTS: dict[str, Effect] = {
    e.cause: e
    for e in (
        Effect("coulomb_friction", "b1", _ALL, 3e-4, 0.0, _INF, "kg m^2/s^2", "pendulum Coulomb friction"),
        Effect("viscous_damping", "b2", _ALL, 4.5e-5, 0.0, _INF, "kg m^2/s", "pendulum viscous damping"),
        Effect("quadratic_drag", "b3", _ALL, 1e-6, 0.0, _INF, "kg m^2", "pendulum air drag"),
        Effect("pendulum_length", "l", _ALL, 0.2, 1e-3, _INF, "m", "effective length"),
        Effect(
            "angle_offset",
            "theta_offset",
            _ALL,
            0.01,
            -_INF,
            _INF,
            "rad",
            "encoder zero offset, measured = true + theta_offset",
        ),
        Effect("oscillator_damping", "C", _OSC, 20.0, 0.0, _INF, "kg/s", "oscillator damping"),
        Effect("oscillator_stiffness", "K", _OSC, 1910.0, 1.0, _INF, "N/m", "oscillator stiffness"),
        Effect("oscillator_mass", "M", _OSC, 10.9, 1e-2, _INF, "kg", "oscillator mass"),
        Effect("spring_hardening", "k3", _OSC, 1e6, -_INF, _INF, "N/m^3", "restoring force K y + k3 y^3"),
        Effect("forcing_gain", "gain", _OSC, 1.0, 1e-3, _INF, "-", "applied force = gain x recorded Fe"),
        Effect("actuator_delay", "tau", ("substructured",), 0.01, 0.0, _INF, "s", "x(t) = y_cmd(t - tau)"),
        Effect("platform_mass", "M2", _RIG, 0.9, 0.0, _INF, "kg", "platform mass"),
        Effect("platform_damping", "C2", _RIG, 10.0, 0.0, _INF, "kg/s", "platform damping"),
        Effect("force_sensor_gain", "gain_Fs", _RIG, 1.0, 1e-3, _INF, "-", "measured Fs = gain_Fs x true Fs"),
    )
}

#: The actuator causes the transfer-system identification names (:mod:`.identify.transfer`), with the
#: parameter each is reported by; they are not fitted by the replays.
ACTUATOR_CAUSES = {
    "actuator_delay": ("tau", "s", "the actuator's effective delay at the forcing frequency differs from nominal"),
    "servo_bandwidth": ("rate", "rad/s", "the servo's natural frequency (second order) differs from nominal"),
    "servo_gain": ("gain_servo", "-", "the actuator's static gain differs from 1 (x = gain x command)"),
}

#: The part of a substructured test each cause belongs to: the numerical model (code), the physical
#: substructure (specimen) or the transfer system (actuator and sensors).
PART_OF = {
    "oscillator_mass": "numerical",
    "oscillator_damping": "numerical",
    "oscillator_stiffness": "numerical",
    "spring_hardening": "numerical",
    "forcing_gain": "numerical",
    "platform_mass": "physical",
    "platform_damping": "physical",
    "pendulum_length": "physical",
    "coulomb_friction": "physical",
    "viscous_damping": "physical",
    "quadratic_drag": "physical",
    "actuator_delay": "transfer",
    "servo_bandwidth": "transfer",
    "servo_gain": "transfer",
    "force_sensor_gain": "transfer",
    "angle_offset": "transfer",
}

#: Parameters that live on the measurement side, with their neutral values.
CHAIN_PARAMS = {"gain": 1.0, "theta_offset": 0.0, "tau": 0.0, "gain_Fs": 1.0}


def applicable(kind: str) -> list[Effect]:
    """Effects identifiable on a record of ``kind``."""
    return [e for e in EFFECTS.values() if kind in e.kinds]


def effect(cause: str) -> Effect:
    if cause not in EFFECTS:
        raise ConfigError(f"unknown cause {cause!r}; the vocabulary is: {', '.join(EFFECTS)}")
    return EFFECTS[cause]


def nominal_values(params: ModelParams, tau: float = 0.0) -> dict[str, float]:
    """Every vocabulary parameter's nominal value: model fields plus chain parameters."""
    values = params.to_dict()
    values.update(CHAIN_PARAMS)
    values["tau"] = tau
    return values


def split_values(values: dict[str, float]) -> tuple[ModelParams, dict[str, float]]:
    """Split extended values into a validated ModelParams and the chain parameters."""
    fields = ModelParams().to_dict()
    model = ModelParams.from_mapping({k: v for k, v in values.items() if k in fields})
    chain = {k: float(values[k]) for k in CHAIN_PARAMS if k in values}
    return model, chain


def model_file(model: ModelParams) -> dict[str, float]:
    """A params file for ``pendsweep sweep --model``: every ModelParams field but the forcing.

    ``alpha`` and ``fe`` are test conditions of the record, not physics, so a
    sweep keeps its own forcing.
    """
    return {k: v for k, v in model.to_dict().items() if k not in ("alpha", "fe")}
