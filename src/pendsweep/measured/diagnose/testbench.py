"""Independent measured-like records for testing the diagnosis (tests and ``make bench``).

This generator shares **no integration code** with the replay kernels
(``pendsweep.kernels``) nor with :mod:`pendsweep.measured.diagnose.synth`: its
right-hand sides are written here from Eqs. (1)-(4) of the paper (the 2 x 2
mass matrix of Eqs. (1)-(2) is solved by Cramer's rule at every stage), it
integrates with its own classical RK4 at a fine step of at most
:data:`FINE_STEP` (0.1 ms) with the friction's sign evaluated at every stage
(the replay holds it over a step), and its substructuring rig differs in form
from the replay's:

* the rig (:mod:`.servo_rig`): commands ramped linearly between ticks or
  held, a transport delay, then a first- or second-order servo (the replays
  interpolate the commands by cubic Hermite splines and identify the servo);
* load cell: the true interface force of Eq. (4) integrated over each
  controller tick (the replay differentiates a momentum), optionally lagged;
* the controller feeds back the *measured* (noisy) force, integrates with RK4
  or central differences, and may send a forward prediction of y*.

The record's metadata carries the user's nominal model and, for
substructured records, the nominal actuator delay ``tau`` that a calibration
of the rig would give (transport, the servo's low-frequency group delay, half
a tick for a held command, and a calibration error), and optionally the servo
itself (:attr:`.servo_rig.Rig.describes_servo`). The default rig is a 40 Hz,
zeta 0.7 servo behind 3 ms; :func:`generate_rig_case` draws rigs and
controllers at random (the servo-rig benchmark, :mod:`pendsweep.bench.rigs`).

Measurement: encoder quantised in steps of 0.0013 rad (Table III), LVDT 10 um
steps, 20 um rms noise and a slow random-walk drift, load cell 0.1 N rms noise
and drift.

Seed ranges: :data:`CALIBRATION_SEEDS` (range A) are the only records the
verdict thresholds of :mod:`pendsweep.measured.diagnose.fit` and :mod:`pendsweep.measured.diagnose.judge.tests` were chosen on;
:data:`TEST_SEEDS` (range B) are what the tests and the ``diagnosis``
benchmark check.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba as nb
import numpy as np
import pandas as pd

from ...errors import ConfigError
from ...model.params import FIG9_PO, TABLE_IV, ModelParams
from ..records import Record
from .effects import ACTUATOR_CAUSES, EFFECTS, nominal_values
from .servo_rig import Rig, _force, _friction, predictor_weights, rig_truth

#: Largest truth integration step [s].
FINE_STEP = 1e-4
#: Seeds the thresholds were chosen on (range A) and seeds the tests and benchmark check (range B).
CALIBRATION_SEEDS = range(0, 100_000)
TEST_SEEDS = range(1_000_000, 1_100_000)
#: Table III encoder step [rad]; LVDT step, noise [m]; load-cell noise [N].
ENCODER_STEP = 0.0013
LVDT_STEP, LVDT_NOISE = 1e-5, 2e-5
FORCE_NOISE = 0.1
#: Platform velocity sensor [m/s] and accelerometer [m/s^2] rms noise (records with ``derivatives``).
VELOCITY_NOISE, ACCELEROMETER_NOISE = 2e-4, 0.02
#: Random-walk drift over a record: LVDT [m], load cell [N] (one sigma at the end).
LVDT_DRIFT, FORCE_DRIFT = 2e-5, 0.05
#: Effects outside the vocabulary: name -> (kinds, meaning).
OUT_OF_VOCABULARY = {
    "encoder_nonlinearity": (
        ("free_decay", "forced", "substructured"),
        "measured theta = theta + a sin(20 theta), a [rad]",
    ),
    "damping_drift": (
        ("free_decay", "forced", "substructured"),
        "pendulum b2 (free decay) or oscillator C (forced) or platform C2 (substructured) grows linearly to (1 + a) x nominal over the record",
    ),
    "stiffness_drift": (("forced",), "oscillator K grows linearly to (1 + a) x nominal over the record"),
    "cubic_damping": (("forced",), "oscillator damping force C y' + a y'^3, a [N s^3/m^3]"),
}


# -- right-hand sides (Eqs. (1)-(2) and the rig), written independently of pendsweep.kernels ----------


@nb.njit(cache=True, inline="always")
def _coupled_acc(y, yd, th, thd, force, m, l, b, g, M, C, c3, K, k3):
    """Accelerations (y'', theta'') of Eqs. (1)-(2) by Cramer's rule on the 2 x 2 mass matrix."""
    s, c = math.sin(th), math.cos(th)
    r1 = force - C * yd - c3 * yd * yd * yd - K * y - k3 * y * y * y - m * l * thd * thd * c
    r2 = -_friction(thd, b[0], b[1], b[2]) - m * g * l * s
    a11, a12, a22 = M + m, m * l * s, m * l * l
    det = a11 * a22 - a12 * a12
    return (r1 * a22 - a12 * r2) / det, (a11 * r2 - a12 * r1) / det


@nb.njit(cache=True)
def free_decay_truth(th, thd, m, l, b, g, h, nsub, n, drift):
    """Fixed-pivot pendulum, RK4 step ``h``, ``nsub`` steps per sample, ``n`` samples.

    ``drift``: b2 grows linearly from b2 to (1 + drift) b2 over the record. Returns theta [n].
    """
    out = np.empty(n)
    out[0] = th
    total = (n - 1) * nsub * h
    bb = b.copy()
    for i in range(1, n):
        for j in range(nsub):
            t = ((i - 1) * nsub + j) * h
            bb[1] = b[1] * (1.0 + drift * t / total)
            inert = m * l * l
            k1x, k1v = thd, -(_friction(thd, bb[0], bb[1], bb[2]) + m * g * l * math.sin(th)) / inert
            x2, v2 = th + 0.5 * h * k1x, thd + 0.5 * h * k1v
            k2x, k2v = v2, -(_friction(v2, bb[0], bb[1], bb[2]) + m * g * l * math.sin(x2)) / inert
            x3, v3 = th + 0.5 * h * k2x, thd + 0.5 * h * k2v
            k3x, k3v = v3, -(_friction(v3, bb[0], bb[1], bb[2]) + m * g * l * math.sin(x3)) / inert
            x4, v4 = th + h * k3x, thd + h * k3v
            k4x, k4v = v4, -(_friction(v4, bb[0], bb[1], bb[2]) + m * g * l * math.sin(x4)) / inert
            th += h * (k1x + 2.0 * k2x + 2.0 * k3x + k4x) / 6.0
            thd += h * (k1v + 2.0 * k2v + 2.0 * k3v + k4v) / 6.0
        out[i] = th
    return out


@nb.njit(cache=True)
def forced_truth(z, m, l, b, g, M, C, c3, K, k3, gain, amps, freqs, sweep, h, nsub, n0, n, drift_c, drift_k):
    """Eqs. (1)-(2) under ``gain`` times the tones and sweep of :func:`.servo_rig._force`; ``n0`` transient
    samples skipped.

    ``drift_c``/``drift_k``: C/K grow linearly to (1 + drift) x over the recorded part.
    Returns (n, 2): y [m], theta [rad] at the recorded samples.
    """
    out = np.empty((n, 2))
    y, yd, th, thd = z[0], z[1], z[2], z[3]
    total = max((n - 1) * nsub * h, h)
    for i in range(n0 + n):
        if i >= n0:
            out[i - n0, 0], out[i - n0, 1] = y, th
        if i == n0 + n - 1:
            break
        for j in range(nsub):
            t = (i * nsub + j) * h
            frac = max(t - n0 * nsub * h, 0.0) / total
            Ci, Ki = C * (1.0 + drift_c * frac), K * (1.0 + drift_k * frac)
            f1 = gain * _force(t, amps, freqs, sweep)
            f2 = gain * _force(t + 0.5 * h, amps, freqs, sweep)
            f4 = gain * _force(t + h, amps, freqs, sweep)
            a1, q1 = _coupled_acc(y, yd, th, thd, f1, m, l, b, g, M, Ci, c3, Ki, k3)
            y2, yd2, th2, thd2 = y + 0.5 * h * yd, yd + 0.5 * h * a1, th + 0.5 * h * thd, thd + 0.5 * h * q1
            a2, q2 = _coupled_acc(y2, yd2, th2, thd2, f2, m, l, b, g, M, Ci, c3, Ki, k3)
            y3, yd3, th3, thd3 = y + 0.5 * h * yd2, yd + 0.5 * h * a2, th + 0.5 * h * thd2, thd + 0.5 * h * q2
            a3, q3 = _coupled_acc(y3, yd3, th3, thd3, f2, m, l, b, g, M, Ci, c3, Ki, k3)
            y4, yd4, th4, thd4 = y + h * yd3, yd + h * a3, th + h * thd3, thd + h * q3
            a4, q4 = _coupled_acc(y4, yd4, th4, thd4, f4, m, l, b, g, M, Ci, c3, Ki, k3)
            y += h * (yd + 2.0 * yd2 + 2.0 * yd3 + yd4) / 6.0
            yd += h * (a1 + 2.0 * a2 + 2.0 * a3 + a4) / 6.0
            th += h * (thd + 2.0 * thd2 + 2.0 * thd3 + thd4) / 6.0
            thd += h * (q1 + 2.0 * q2 + 2.0 * q3 + q4) / 6.0
    return out


# -- records ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One generated record.

    Attributes
    ----------
    kind : {"free_decay", "forced", "substructured"}
    effects : dict
        Vocabulary causes hidden in the truth: ``{cause: truth value}`` in the parameter's unit.
    extra : dict
        Out-of-vocabulary effects (:data:`OUT_OF_VOCABULARY`): ``{name: magnitude}``.
    rate : float
        Sample rate [Hz] (the controller rate of substructured records).
    duration : float
        Recorded length [s].
    seed : int
        Seed of noise and drift.
    theta_init : float
        Pendulum angle at release (free decay) or at the start of the transient [rad].
    tones : tuple of (float, float)
        Force tones (amplitude [N], frequency [Hz]); the first is the nominal forcing.
    transient : float
        Seconds simulated before recording (forced, substructured).
    rig : Rig
        The substructuring rig and controller (substructured records).
    sweep : tuple of float
        A linear sweep ``(amplitude [N], f0 [Hz], f1 [Hz])`` over the whole simulated time (transient
        and record) added to the tones; empty: none.
    derivatives : bool
        Substructured records: also the platform's measured velocity ``ydot`` and acceleration ``yddot``
        (sampled at the tick, with :data:`VELOCITY_NOISE` and :data:`ACCELEROMETER_NOISE`).
    """

    kind: str
    effects: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    rate: float = 500.0
    duration: float = 16.0
    seed: int = 0
    theta_init: float = 1.0
    tones: tuple = ((5.0, 2.2), (2.0, 1.3))
    transient: float = 20.0
    rig: Rig = Rig()
    sweep: tuple = ()
    derivatives: bool = False

    @property
    def label(self) -> str:
        """The answer a perfect diagnosis gives: causes joined by ``+``, or ``none``."""
        return "+".join(sorted(self.effects)) or "none"


def nominal_for(kind: str) -> ModelParams:
    """The user's nominal model of a generated record: Table IV; Fig. 9(a) forcing when forced."""
    return TABLE_IV if kind == "free_decay" else FIG9_PO


def generate(case: Case) -> Record:
    """The measured record of ``case`` (nominal model in its metadata, effects hidden)."""
    kind = case.kind
    if kind not in ("free_decay", "forced", "substructured"):
        raise ConfigError(f"kind {kind!r}; choose free_decay, forced or substructured")
    for name in case.extra:
        if name not in OUT_OF_VOCABULARY or kind not in OUT_OF_VOCABULARY[name][0]:
            raise ConfigError(f"out-of-vocabulary effect {name!r} does not apply to kind {kind!r}")
    nominal = nominal_for(kind)
    truth = nominal_values(nominal)
    for cause, value in case.effects.items():
        if cause in ACTUATOR_CAUSES and kind == "substructured":
            continue  # set on the rig below
        eff = EFFECTS[cause]
        if kind not in eff.kinds:
            raise ConfigError(f"cause {cause!r} does not apply to kind {kind!r}")
        truth[eff.param] = float(value)
    rng = np.random.default_rng(case.seed)
    dt = 1.0 / case.rate
    nsub = max(1, math.ceil(dt / FINE_STEP - 1e-9))
    h = dt / nsub
    n = int(round(case.duration * case.rate)) + 1
    t = np.arange(n) * dt
    b = np.array([truth["b1"], truth["b2"], truth["b3"]])
    m, l, g = truth["m"], truth["l"], truth["g"]
    ex = case.extra
    if kind == "free_decay":
        theta = free_decay_truth(case.theta_init, 0.0, m, l, b, g, h, nsub, n, ex.get("damping_drift", 0.0))
        data = pd.DataFrame({"t": t, "theta": _encoder(theta + truth["theta_offset"], ex, rng)})
        return Record(data, kind, nominal, name=f"testbench:{case.label}:{case.seed}")
    amps = np.array([a for a, _ in case.tones], dtype=np.float64)
    freqs = np.array([f for _, f in case.tones], dtype=np.float64)
    n0 = int(round(case.transient * case.rate))
    sweep = np.array([*case.sweep, (n0 + n - 1) * dt] if case.sweep else [0.0, 0.0, 0.0, 1.0])
    # The frequency an actuator is judged at: the main tone's, else the sweep's middle.
    forcing = {"alpha": nominal.alpha, "fe": nominal.fe}
    if not case.tones:
        forcing = {"alpha": float(case.sweep[0]), "fe": 0.5 * float(case.sweep[1] + case.sweep[2])}
    z = np.array([0.0, 0.0, case.theta_init, 0.0])
    if kind == "forced":
        rec = forced_truth(
            z,
            m,
            l,
            b,
            g,
            truth["M"],
            truth["C"],
            ex.get("cubic_damping", 0.0),
            truth["K"],
            truth["k3"],
            truth["gain"],
            amps,
            freqs,
            sweep,
            h,
            nsub,
            n0,
            n,
            ex.get("damping_drift", 0.0),
            ex.get("stiffness_drift", 0.0),
        )
        fe = np.array([_force(ti, amps, freqs, sweep) for ti in t + n0 * dt])
        data = pd.DataFrame(
            {
                "t": t,
                "theta": _encoder(rec[:, 1] + truth["theta_offset"], ex, rng),
                "y": _lvdt(rec[:, 0], rng),
                "Fe": fe + rng.normal(0.0, FORCE_NOISE, n) + _drift(n, FORCE_DRIFT, rng),
            }
        )
        return Record(data, kind, nominal, forcing=forcing, name=f"testbench:{case.label}:{case.seed}")
    # Substructured: the numerical model's M1, C1 are code (nominal split); M, C effects move them.
    M1 = truth["M"] - nominal.M2
    C1 = truth["C"] - nominal.C2
    rig = case.rig
    # A record that declares its held command is replayed with the hold: its nominal leaves the half tick out.
    half_tick = 0.5 * dt if rig.hold and not rig.declares_daq else 0.0
    tau_nominal = rig.effective_delay(dt) - (0.5 * dt if rig.hold and rig.declares_daq else 0.0) + rig.calibration_error
    wn = rig.wn * case.effects.get("servo_bandwidth", 1.0)
    # An actuator_delay effect sets the true effective delay; the servo's own share stays.
    delay = rig.delay
    if "actuator_delay" in case.effects:
        delay = case.effects["actuator_delay"] - (rig.effective_delay(dt) - rig.delay)
    servo_gain = case.effects.get("servo_gain", 1.0)
    fs_noise = rng.normal(0.0, FORCE_NOISE, n0 + n) + np.concatenate([np.zeros(n0), _drift(n, FORCE_DRIFT, rng)])
    rec = rig_truth(
        z, m, l, b, g, M1, C1, truth["K"], truth["k3"], truth["M2"], truth["C2"], truth["gain"], truth["gain_Fs"],
        amps, freqs, sweep, dt, nsub, n0, n, delay, rig.servo_order, wn, rig.servo_zeta, servo_gain, fs_noise,
        ex.get("damping_drift", 0.0), rig.hold, predictor_weights(rig.lead, dt), rig.load_cell_tau, rig.integrator,
        int(rig.point_load_cell),
    )  # fmt: skip
    data = pd.DataFrame(
        {
            "t": t,
            "theta": _encoder(rec[:, 1] + truth["theta_offset"], ex, rng),
            "y": _lvdt(rec[:, 0], rng),
            "Fe": rec[:, 4],
            "y_cmd": rec[:, 3],
            "Fs": rec[:, 2],
        }
    )
    if case.derivatives:
        data["ydot"] = rec[:, 6] + rng.normal(0.0, VELOCITY_NOISE, n)
        data["yddot"] = rec[:, 7] + rng.normal(0.0, ACCELEROMETER_NOISE, n)
    daq = {}
    if rig.declares_daq:
        daq = {
            "load_cell": "point" if rig.point_load_cell else "tick_mean",
            "command": "held" if rig.hold else "ramped",
        }
    actuator = {}
    if rig.describes_servo:
        actuator = {"model": "second_order" if rig.servo_order == 2 else "first_order", "gain": 1.0,
                    "tau": rig.delay + half_tick + rig.calibration_error, "rate": rig.wn}  # fmt: skip
        if rig.servo_order == 2:
            actuator["zeta"] = rig.servo_zeta
    return Record(
        data,
        kind,
        nominal,
        tau=tau_nominal,
        forcing=forcing,
        name=f"testbench:{case.label}:{case.seed}",
        actuator=actuator,
        daq=daq,
    )


def _drift(n: int, final_sigma: float, rng: np.random.Generator) -> np.ndarray:
    """A random walk reaching about ``final_sigma`` at the end of ``n`` samples."""
    return np.cumsum(rng.normal(0.0, final_sigma / math.sqrt(n), n))


def _encoder(theta: np.ndarray, extra: dict, rng: np.random.Generator) -> np.ndarray:
    a = extra.get("encoder_nonlinearity", 0.0)
    return ENCODER_STEP * np.round((theta + a * np.sin(20.0 * theta)) / ENCODER_STEP)


def _lvdt(y: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    noisy = y + rng.normal(0.0, LVDT_NOISE, y.shape) + _drift(len(y), LVDT_DRIFT, rng)
    return LVDT_STEP * np.round(noisy / LVDT_STEP)
