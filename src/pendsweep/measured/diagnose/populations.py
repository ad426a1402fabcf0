"""The diagnosis benchmark's populations: random cases drawn from seeds, for calibration and for testing.

Calibration draws seeds from :data:`~.testbench.CALIBRATION_SEEDS` (range A)
and the benchmark from :data:`~.testbench.TEST_SEEDS` (range B), so nothing
is tuned on the records it is judged by. Each draw is a :class:`~.testbench.Case`
that :func:`~.testbench.generate` turns into a record: single effects and
pairs of them (:func:`draw_case`), servo-rig records (:func:`draw_rig_case`,
:func:`generate_rig_session`) and the oscillator's look-alikes under
forcings that can or cannot tell them apart (:func:`draw_look_alike_case`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...errors import ConfigError
from ..records import Record
from .effects import EFFECTS, nominal_values
from .servo_rig import SERVO_DELAY, SERVO_WN, SERVO_ZETA, Rig
from .testbench import OUT_OF_VOCABULARY, Case, generate, nominal_for

#: Identifiable ranges of single effects per kind: cause -> (mode, lo, hi); the truth is
#: nominal x U(lo, hi) ("x"), U(lo, hi) ("abs"), or the record's nominal + U(lo, hi) ("add").
RANGES = {
    "free_decay": {
        "coulomb_friction": ("x", 2.0, 5.0),
        "viscous_damping": ("x", 2.0, 5.0),
        "quadratic_drag": ("x", 3.0, 8.0),
        "pendulum_length": ("x", 1.03, 1.10),
        "angle_offset": ("abs", 0.005, 0.02),
    },
    "forced": {
        "oscillator_damping": ("x", 1.2, 1.5),
        "oscillator_stiffness": ("x", 1.04, 1.10),
        "oscillator_mass": ("x", 1.05, 1.12),
        "spring_hardening": ("abs", 8e5, 2e6),
        "forcing_gain": ("x", 1.05, 1.15),
        "pendulum_length": ("x", 1.03, 1.08),
        "angle_offset": ("abs", 0.01, 0.02),
    },
    "substructured": {
        "oscillator_damping": ("x", 1.2, 1.5),
        "oscillator_stiffness": ("x", 1.04, 1.10),
        "oscillator_mass": ("x", 1.05, 1.12),
        "spring_hardening": ("abs", 8e5, 2e6),
        "forcing_gain": ("x", 1.08, 1.15),
        "pendulum_length": ("x", 1.03, 1.08),
        "angle_offset": ("abs", 0.07, 0.10),
        "actuator_delay": ("add", 0.003, 0.008),
        "platform_mass": ("x", 1.3, 1.6),
        "platform_damping": ("x", 1.3, 1.6),
        "force_sensor_gain": ("x", 1.15, 1.3),
    },
}
#: Causes that a pendulum at rest (theta exactly constant) cannot show.
PENDULUM_CAUSES = {"coulomb_friction", "viscous_damping", "quadratic_drag", "pendulum_length", "angle_offset"}
#: Pairs drawn for two-effect records (effects on different parts of the model).
PAIRS = {
    "free_decay": [
        ("pendulum_length", "coulomb_friction"),
        ("pendulum_length", "viscous_damping"),
        ("angle_offset", "quadratic_drag"),
    ],
    "forced": [
        ("oscillator_damping", "pendulum_length"),
        ("spring_hardening", "forcing_gain"),
        ("oscillator_stiffness", "angle_offset"),
    ],
    "substructured": [
        ("actuator_delay", "oscillator_damping"),
        ("platform_mass", "pendulum_length"),
        ("spring_hardening", "force_sensor_gain"),
    ],
}
#: Magnitude ranges of the out-of-vocabulary effects.
OOV_RANGES = {
    "encoder_nonlinearity": (0.003, 0.006),
    "damping_drift": (1.0, 2.0),
    "stiffness_drift": (0.05, 0.10),
    "cubic_damping": (200.0, 500.0),
}
DURATION = {"free_decay": 20.0, "forced": 16.0, "substructured": 12.0}
#: Shares of a population: clean, one effect, two effects, out of vocabulary.
MIX = (0.2, 0.5, 0.15, 0.15)


def truth_value(kind: str, cause: str, u: float, rate: float) -> float:
    """The truth of ``cause`` at position ``u`` in [0, 1] of its identifiable range."""
    mode, lo, hi = RANGES[kind][cause]
    v = lo + u * (hi - lo)
    if mode == "abs":
        return v
    if mode == "add":
        return SERVO_DELAY + 2.0 * SERVO_ZETA / SERVO_WN + v
    return v * nominal_values(nominal_for(kind))[EFFECTS[cause].param]


def draw_case(seed: int, category: str | None = None, kind: str | None = None) -> tuple[str, Case]:
    """A random case of the population: ``(category, case)``, category in clean/single/pair/oov.

    Random: kind, category (shares :data:`MIX`), cause(s) and magnitude(s) within
    the identifiable ranges, sampling rate (500 Hz or 2 kHz), initial angle
    (forced records start at rest in a quarter of the cases: theta stays exactly 0),
    a second or third force tone; the noise realisation is seeded by ``seed``.
    """
    rng = np.random.default_rng([seed, 11])
    kind = kind or str(rng.choice(["free_decay", "forced", "substructured"]))
    category = category or str(rng.choice(["clean", "single", "pair", "oov"], p=MIX))
    rate = float(rng.choice([500.0, 2000.0]))
    tones = ((5.0, 2.2), (float(rng.uniform(1.5, 3.0)), float(rng.uniform(1.1, 1.6))))
    if rng.uniform() < 0.3:
        tones = tones + ((float(rng.uniform(0.5, 1.5)), float(rng.uniform(2.6, 3.5))),)
    at_rest = kind == "forced" and category in ("clean", "single") and rng.uniform() < 0.25
    effects: dict[str, float] = {}
    extra: dict[str, float] = {}
    if category == "single":
        choices = [c for c in RANGES[kind] if not (at_rest and c in PENDULUM_CAUSES)]
        cause = str(rng.choice(choices))
        effects[cause] = truth_value(kind, cause, rng.uniform(), rate)
    elif category == "pair":
        a, b = PAIRS[kind][int(rng.integers(len(PAIRS[kind])))]
        effects = {a: truth_value(kind, a, rng.uniform(), rate), b: truth_value(kind, b, rng.uniform(), rate)}
    elif category == "oov":
        names = [k for k, (kinds, _) in OUT_OF_VOCABULARY.items() if kind in kinds]
        name = str(rng.choice(names))
        extra[name] = float(rng.uniform(*OOV_RANGES[name]))
    theta_init = 0.0 if at_rest else float(rng.uniform(0.6, 1.5) if kind == "free_decay" else rng.uniform(0.2, 0.5))
    duration = DURATION[kind] * (0.5 if rate > 1000.0 else 1.0)  # 2 kHz records: same samples budget halved
    return category, Case(kind, effects, extra, rate, duration, int(seed), theta_init, tones)


# -- the servo-rig population: substructured tests on rigs and controllers unlike the replay's (issue 22) ----------

#: Single effects of servo-rig records: cause -> (mode, lo, hi) as :data:`RANGES`; ``rig_x`` multiplies the
#: servo's frequency, ``abs`` sets the actuator's gain, ``add`` adds to the rig's true effective delay.
RIG_RANGES = {
    **{  # the numerical model and the pendulum: as on forced records
        cause: RANGES["forced"][cause]
        for cause in (
            "oscillator_damping",
            "oscillator_stiffness",
            "oscillator_mass",
            "spring_hardening",
            "forcing_gain",
            "pendulum_length",
        )
    },  # fmt: skip
    "platform_mass": ("x", 1.3, 1.6),
    "platform_damping": ("x", 1.3, 1.6),
    "force_sensor_gain": ("x", 1.15, 1.3),
    "angle_offset": ("abs", 0.07, 0.10),
    "actuator_delay": ("add", 0.003, 0.008),
    "servo_bandwidth": ("rig_x", 0.3, 0.5),
    "servo_gain": ("abs", 0.90, 0.95),
}
#: Causes the record's signature cannot always tell from a partner (the look-alike pairs of issue 22):
#: a verdict naming the partner with the truth among its ties counts as right.
LOOK_ALIKES = {
    "oscillator_stiffness": "spring_hardening",
    "spring_hardening": "oscillator_stiffness",
    "oscillator_damping": "forcing_gain",
    "forcing_gain": "oscillator_damping",
    "oscillator_mass": "actuator_delay",
    "actuator_delay": "oscillator_mass",
    "servo_bandwidth": "oscillator_mass",
    "viscous_damping": "quadratic_drag",
    "quadratic_drag": "viscous_damping",
}
#: Shares of the servo-rig population: clean, one effect.
RIG_MIX = (0.3, 0.7)


def draw_rig(rng: np.random.Generator) -> Rig:
    """A random rig and controller: servo order and bandwidth, transport delay, hold, predictor, load cell, integrator."""
    order = 2 if rng.uniform() < 0.7 else 1
    if order == 2:
        hz = 300.0 if rng.uniform() < 0.1 else float(rng.uniform(15.0, 60.0))
    else:
        hz = float(rng.uniform(15.0, 40.0))
    zeta = float(rng.uniform(0.5, 0.9))
    delay = float(rng.uniform(0.002, 0.016))
    rig = Rig(order, hz, zeta, delay)
    lag = rig.servo_lag()
    return Rig(
        servo_order=order,
        servo_hz=hz,
        servo_zeta=zeta,
        delay=delay,
        hold=int(rng.uniform() < 0.3),
        lead=float(rng.uniform(0.5, 1.0) * (delay + lag)) if rng.uniform() < 0.3 else 0.0,
        load_cell_tau=float(rng.uniform(2e-4, 1e-3)) if rng.uniform() < 0.3 else 0.0,
        integrator=int(rng.uniform() < 0.3),
        calibration_error=float(rng.uniform(-5e-4, 5e-4)),
        describes_servo=bool(rng.uniform() < 0.5),
    )


def draw_rig_case(seed: int, category: str | None = None, attempt: int = 0) -> tuple[str, Case]:
    """A random servo-rig record: ``(category, case)`` with category ``clean`` or ``single`` (:data:`RIG_MIX`).

    Random: the rig (:func:`draw_rig`), the sampling rate (500 Hz or 2 kHz), a second (and in 30 % a
    third) force tone, the initial angle, the hidden cause and its size within :data:`RIG_RANGES`.
    ``attempt`` draws another case for the same seed (:func:`generate_rig_case`).
    """
    rng = np.random.default_rng([seed, 22, attempt])
    category = category or str(rng.choice(["clean", "single"], p=RIG_MIX))
    rate = float(rng.choice([500.0, 2000.0]))
    tones = ((5.0, 2.2), (float(rng.uniform(1.5, 3.0)), float(rng.uniform(1.1, 1.6))))
    if rng.uniform() < 0.3:
        tones = tones + ((float(rng.uniform(0.5, 1.5)), float(rng.uniform(2.6, 3.5))),)
    rig = draw_rig(rng)
    effects: dict[str, float] = {}
    if category == "single":
        cause = str(rng.choice(list(RIG_RANGES)))
        mode, lo, hi = RIG_RANGES[cause]
        v = lo + rng.uniform() * (hi - lo)
        if mode == "x":
            v *= nominal_values(nominal_for("substructured"))[EFFECTS[cause].param]
        elif mode == "add":
            v += rig.effective_delay(1.0 / rate)
        effects[cause] = float(v)
    theta_init = float(rng.uniform(0.2, 0.5))
    duration = DURATION["substructured"] * (0.5 if rate > 1000.0 else 1.0)
    return category, Case("substructured", effects, {}, rate, duration, int(seed), theta_init, tones, rig=rig)


#: Draws per seed before a servo-rig case is given up (a drawn test may be unstable, as real ones are).
RIG_ATTEMPTS = 5


def generate_rig_case(seed: int, category: str | None = None) -> tuple[str, Case, Record]:
    """The first stable test among :data:`RIG_ATTEMPTS` draws of ``seed``: ``(category, case, record)``.

    A drawn rig and controller can make the test unstable (a long predictor lead at a fast rate): it
    diverges and leaves no record, as it would in a lab; the next draw is taken.
    """
    for attempt in range(RIG_ATTEMPTS):
        category_, case = draw_rig_case(seed, category, attempt)
        try:
            return category_, case, generate(case)
        except ConfigError:
            continue
    raise ConfigError(f"seed {seed}: no stable servo-rig test in {RIG_ATTEMPTS} draws")


# -- look-alike records (issue 34): the oscillator's stiffness, mass or hardening under forcing that separates them ----

#: The oscillator's look-alike causes: a stiffer or softer spring, a heavier or lighter mass, a hardening spring.
LOOK_ALIKE_CAUSES = ("oscillator_stiffness", "oscillator_mass", "spring_hardening")
#: Forcings of the look-alike records and their shares: two tones either side of the oscillator's
#: resonance (the true natural frequency may lie between the nominal one and a tone), a sweep through
#: it, one tone from rest (a start-up transient at the natural frequency), one tone in steady state.
LOOK_ALIKE_FORCINGS = {"two_tones": 0.3, "sweep": 0.3, "start_up": 0.25, "one_tone": 0.15}
#: The forcings whose records can separate the look-alikes: one tone in steady state cannot (only
#: ``K - M omega^2`` is seen, and a cubic spring acts as a constant stiffness at a constant amplitude).
SEPARATING_FORCINGS = ("two_tones", "sweep", "start_up")


def draw_look_alike_case(seed: int, kind: str, attempt: int = 0) -> tuple[str, Case]:
    """A random look-alike record of ``kind`` (forced or substructured): ``(forcing, case)``.

    Random: the cause (:data:`LOOK_ALIKE_CAUSES`) and its size within :data:`RANGES` (a coded change of
    the numerical model in a substructured test), the forcing (:data:`LOOK_ALIKE_FORCINGS`), the rate
    (500 Hz or 2 kHz), the pendulum's initial angle (0.05-0.5 rad: small swings too), and for
    substructured records the rig and controller (:func:`draw_rig`). ``attempt`` draws another case for
    the same seed (:func:`generate_look_alike_case`).
    """
    if kind not in ("forced", "substructured"):
        raise ConfigError(f"look-alike records are forced or substructured, not {kind!r}")
    rng = np.random.default_rng([seed, 34, attempt])
    cause = str(rng.choice(LOOK_ALIKE_CAUSES))
    forcing = str(rng.choice(list(LOOK_ALIKE_FORCINGS), p=list(LOOK_ALIKE_FORCINGS.values())))
    rate = float(rng.choice([500.0, 2000.0]))
    value = truth_value(kind, cause, float(rng.uniform()), rate)
    theta_init = float(rng.uniform(0.05, 0.5))
    tones: tuple = ((5.0, 2.2),)
    sweep: tuple = ()
    transient = 20.0
    if forcing == "two_tones":
        tones = ((5.0, float(rng.uniform(1.8, 2.1))), (float(rng.uniform(2.0, 5.0)), float(rng.uniform(2.3, 2.8))))
    elif forcing == "sweep":
        tones, sweep, transient = (), (5.0, float(rng.uniform(1.4, 1.8)), float(rng.uniform(2.6, 3.2))), 4.0
    elif forcing == "start_up":
        transient = 0.0
    rig = draw_rig(rng) if kind == "substructured" else Rig()
    duration = DURATION[kind] * (0.5 if rate > 1000.0 else 1.0)
    case = Case(kind, {cause: value}, {}, rate, duration, int(seed), theta_init, tones, transient, rig=rig, sweep=sweep)
    return forcing, case


def generate_look_alike_case(seed: int, kind: str) -> tuple[str, Case, Record]:
    """The look-alike record of ``seed``: ``(forcing, case, record)``; an unstable servo-rig test is drawn again
    (up to :data:`RIG_ATTEMPTS` times, as :func:`generate_rig_case`)."""
    for attempt in range(RIG_ATTEMPTS):
        forcing, case = draw_look_alike_case(seed, kind, attempt)
        try:
            return forcing, case, generate(case)
        except ConfigError:
            continue
    raise ConfigError(f"seed {seed}: no stable look-alike test in {RIG_ATTEMPTS} draws")


def generate_rig_session(seed: int, records: int = 3) -> tuple[str, list[Case], list[Record]]:
    """Several records of one servo rig, one controller and one hidden effect (the rig of
    :func:`generate_rig_case`), each with its own second tone, initial angle and noise: what a lab
    diagnoses jointly. Returns ``(category, cases, records)``."""
    category, case, record = generate_rig_case(seed)
    cases, out = [case], [record]
    rng = np.random.default_rng([seed, 35])
    for _ in range(RIG_ATTEMPTS * records):
        if len(out) == records:
            return category, cases, out
        tones = ((5.0, 2.2), (float(rng.uniform(1.5, 3.0)), float(rng.uniform(1.1, 1.6))))
        variant = replace(case, seed=int(rng.integers(2**31)), tones=tones, theta_init=float(rng.uniform(0.2, 0.5)))
        try:
            out.append(generate(variant))
        except ConfigError:  # this tone made the test unstable: draw another
            continue
        cases.append(variant)
    if len(out) < records:
        raise ConfigError(f"seed {seed}: {len(out)} stable records of one rig in {RIG_ATTEMPTS * records} draws")
    return category, cases, out
