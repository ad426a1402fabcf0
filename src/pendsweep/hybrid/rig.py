"""The virtual rig an experimental site serves: the paper's physical substructure behind a transfer system.

The rig is the pendulum on its platform (M2, C2) moved by the actuator of
the substructured backend (``ideal``, ``delay`` or ``servo``), read by its
load cell, LVDT and encoder; the arithmetic is the backend's own
(:mod:`pendsweep.kernels._site`). A site holds two copies of its state:

* the **committed** state, at the time of the last commitState;
* the **trial** state, rebuilt from the committed one by every trial, so
  any number of trials before a commit never advance the rig.

A trial at the committed time (OpenSees sends one at t = 0) holds the rig
where it is. The step is fixed by the first trial (the command delay line
needs a constant one); a later trial at another step is refused.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..backends.substructured import SubstructuredBackend
from ..errors import ConfigError
from ..kernels._site import N_READINGS, READING_NAMES, rig_reading, rig_trial
from ..kernels._substructured import S_THETA, S_X
from ..model.params import ModelParams
from .protocol import ProtocolError

#: Noise is drawn in blocks of this many steps from ``default_rng([seed, block])``,
#: so any step's noise is known without drawing the ones before it.
NOISE_BLOCK = 65536
#: Relative tolerance on a trial's step against the constant one.
STEP_TOLERANCE = 1e-6
#: Steps a rig accepts [s]: 10 us (the command delay line holds transport_delay / step samples) to 50 ms.
MIN_STEP, MAX_STEP = 1e-5, 0.05
#: Smallest alpha of OpenSees's AlphaOS (2/3): a first step this much shorter than the second is accepted.
ALPHA_MIN = 2.0 / 3.0 - 1e-9
READING_INDEX = {name: i for i, name in enumerate(READING_NAMES)}


@dataclass(frozen=True)
class RigLimits:
    """What the rig refuses to do (a trial beyond them stops the test, the rig held).

    Attributes
    ----------
    stroke : float
        Largest commanded or achieved platform displacement ``|x|`` [m]
        (default 0.075: the LVDT's +-75 mm, Table III).
    velocity : float
        Largest commanded platform velocity ``|v|`` [m/s] (default 1.0, an
        assumed actuator rating; the paper gives none).
    force : float
        Largest load-cell reading ``|F_s|`` [N] (default 250: the load cell's
        range, Table III).
    """

    stroke: float = 0.075
    velocity: float = 1.0
    force: float = 250.0

    def __post_init__(self) -> None:
        for name, option, unit in (("stroke", "stroke", "m"), ("velocity", "velocity_limit", "m/s"),
                                   ("force", "force_limit", "N")):  # fmt: skip
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"-B {option}={value!r} {unit}: the rig's limit must be a finite number > 0")


class SiteRig:
    """The rig of one experimental site (see the module docstring).

    Parameters
    ----------
    backend : SubstructuredBackend
        Transfer-system and sensor options (its controller options are unused).
    params : ModelParams
        Physical parameters: the pendulum (m, l, b1, b2, b3, g) and the
        platform (M2, C2); ``fe`` sets the phase of the load cell's odd harmonics.
    theta0, thetadot0 : float
        Initial pendulum angle [rad] and rate [rad/s]; the platform starts at rest at 0.
    limits : RigLimits
    report_mass : bool
        Report the carried mass ``M2 + m`` through getMass and return the
        load cell's force less that mass times the platform's measured
        acceleration (default); False: mass 0 and the whole force.
    """

    def __init__(
        self,
        backend: SubstructuredBackend,
        params: ModelParams,
        theta0: float = 0.1,
        thetadot0: float = 0.0,
        limits: RigLimits | None = None,
        report_mass: bool = True,
    ) -> None:
        self.backend = backend
        self.params = params
        self.theta0 = theta0
        self.thetadot0 = thetadot0
        self.limits = limits or RigLimits(stroke=backend.stroke)
        self.report_mass = report_mass
        self.carried_mass = params.M2 + params.m
        self._p = params.kernel_array()
        self._pend = (params.m, params.l, params.b1, params.b2, params.b3, params.g)
        self._blocks: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.nudges_pending = 0.0  # the operator's hand, applied before the next step (:meth:`request_nudge`)
        self.reset()

    # -- state ------------------------------------------------------------------------
    def reset(self) -> None:
        """The rig at its initial state, time 0, step not yet known (no nudge applied yet)."""
        self.nudged: list[tuple[float, float]] = []  # (time [s], angle [rad]) of each nudge applied
        self.dt: float | None = None
        self.first_step: float | None = None
        self._configure(self.backend.dt)
        self.committed_time = 0.0
        self.committed_step = 0
        state = self._backend.initial_state(self.params, 0.0, 0.0, self.theta0, self.thetadot0)
        self.committed_readings = np.zeros(N_READINGS)
        nf, nx = self._noise(0)
        rig_reading(state, self._p, self._cfg, self._dt, nf, nx, 0.0, self.committed_readings)
        self.committed = state
        self.trial_state = state.copy()
        self.readings = self.committed_readings.copy()
        self.trial_time = 0.0
        self.trial_command = (0.0, 0.0, 0.0)

    def _configure(self, dt: float) -> None:
        self._backend = dataclasses.replace(self.backend, dt=dt)
        self._cfg = self._backend.loop_settings(self.params, dt=dt)
        self._dt = dt

    def _noise(self, step: int) -> tuple[float, float]:
        block, i = divmod(step, NOISE_BLOCK)
        if block not in self._blocks:
            if len(self._blocks) > 4:
                self._blocks.clear()
            rng = np.random.default_rng([self.backend.seed, block])
            self._blocks[block] = (
                rng.standard_normal(NOISE_BLOCK) * self.backend.force_noise,
                rng.standard_normal(NOISE_BLOCK) * self.backend.lvdt_noise,
            )
        nf, nx = self._blocks[block]
        return float(nf[i]), float(nx[i])

    def _fix_step(self, dt: float) -> None:
        """Fix the constant step (the first trial's, or the second's after a short first one).

        The delay line is rebuilt for it, the rig's own state unchanged.
        """
        if self._backend.n_cmd != dataclasses.replace(self.backend, dt=dt).n_cmd:
            old = self.committed
            self._configure(dt)
            fresh = self._backend.initial_state(self.params, 0.0, 0.0, self.theta0, self.thetadot0)
            fresh[:12] = old[:12]
            self.committed = fresh
        else:
            self._configure(dt)
        self.dt = dt

    # -- the protocol's verbs ---------------------------------------------------------
    def trial(self, d: float, v: float, a: float, t: float | None) -> np.ndarray:
        """Rebuild the trial state: the committed rig moved to command ``d`` [m], ``v`` [m/s] at time ``t`` [s].

        ``a`` [m/s^2] is recorded, not used (the actuator's own acceleration
        comes from its dynamics). ``t`` None: one step of the site's ``dt``.
        Returns the readings (:data:`READING_NAMES`). Raises
        :class:`ProtocolError` for a non-finite value, a command beyond the
        limits, time going backwards, a changed step, or a reading beyond
        the load cell's range; the committed rig is then untouched.
        """
        try:
            return self._trial(d, v, a, t)
        except ConfigError as exc:  # options that no step of this client can serve
            raise ProtocolError(f"the rig cannot run this client's step: {exc}") from None

    def request_nudge(self, angle: float) -> None:
        """The operator nudges the pendulum by ``angle`` [rad] before the next step (safe from a signal handler).

        The pivot moves vertically, so the hanging pendulum is an invariant of
        the rig, and its Coulomb friction keeps it at rest against small
        disturbances well past the stability boundary: in the paper's lab "the
        transition is instigated by perturbing the pendulum by theta = 0.1 rad"
        (Fig. 8), by hand. A client cannot do that through the protocol.
        """
        self.nudges_pending += angle

    def _trial(self, d: float, v: float, a: float, t: float | None) -> np.ndarray:
        if self.nudges_pending:  # between two steps, as a hand would: the committed state moves
            angle, self.nudges_pending = self.nudges_pending, 0.0
            self.committed[S_THETA] += angle
            self.nudged.append((self.committed_time, angle))
        for name, value in (("displacement", d), ("velocity", v), ("acceleration", a)):
            if not math.isfinite(value):
                raise ProtocolError(f"trial {name} {value!r} is not finite")
        if t is not None and not math.isfinite(t):
            raise ProtocolError(f"trial time {t!r} is not finite")
        lim = self.limits
        if abs(d) > lim.stroke:
            raise ProtocolError(f"trial displacement {d:.6g} m beyond the rig's stroke +-{lim.stroke:g} m")
        if abs(v) > lim.velocity:
            raise ProtocolError(f"trial velocity {v:.6g} m/s beyond the rig's limit +-{lim.velocity:g} m/s")
        step = (self.dt or self.backend.dt) if t is None else t - self.committed_time
        scale = self.dt or self.backend.dt
        if t is not None and abs(step) <= STEP_TOLERANCE * scale:  # a trial at the committed time holds the rig
            self.trial_state = self.committed.copy()
            self.readings = self.committed_readings.copy()
            self.trial_time = self.committed_time
            self.trial_command = (d, v, a)
            return self.readings
        if step < 0:
            raise ProtocolError(f"trial time {t:.9g} s is before the committed time {self.committed_time:.9g} s")
        if not MIN_STEP <= step <= MAX_STEP:
            raise ProtocolError(f"trial step {step:.6g} s outside the rig's accepted {MIN_STEP:g} to {MAX_STEP:g} s")
        if self.committed_step == 1 and self.dt == self.first_step and step > self.dt >= ALPHA_MIN * step:
            # OpenSees's AlphaOS with alpha < 1 evaluates at t + alpha dt: a first step alpha dt, then dt
            self._fix_step(step)
        if self.dt is None:
            self._fix_step(step)
            self.first_step = step
        elif abs(step - self.dt) > STEP_TOLERANCE * self.dt:
            raise ProtocolError(
                f"trial step {step:.9g} s differs from the constant step {self.dt:.9g} s "
                "(the rig's command delay line needs a constant step)"
            )
        state = self.committed.copy()
        out = np.empty(N_READINGS)
        n = self.committed_step + 1
        nf, nx = self._noise(n)
        time_next = self.committed_time + self.dt if t is None else t
        phase = 2.0 * math.pi * self.params.fe * time_next
        x_before = state[S_X]
        rig_trial(state, d, v, self._p, self._pend, self._cfg, self.dt, nf, nx, phase, out)
        if not np.all(np.isfinite(out)):
            raise ProtocolError(f"the rig diverged at t = {time_next:.6g} s (non-finite state)")
        if abs(out[READING_INDEX["x"]]) > lim.stroke:
            raise ProtocolError(f"platform at {out[READING_INDEX['x']]:.6g} m beyond the stroke +-{lim.stroke:g} m")
        # the platform's own speed, whatever velocity the client declared (or left out)
        speed = max(abs(out[READING_INDEX["xdot"]]), abs(out[READING_INDEX["x"]] - x_before) / self.dt)
        if speed > lim.velocity:
            raise ProtocolError(f"platform moved at {speed:.6g} m/s, beyond the rig's limit +-{lim.velocity:g} m/s")
        if abs(out[READING_INDEX["Fs"]]) > lim.force:
            raise ProtocolError(f"load cell reads {out[READING_INDEX['Fs']]:.6g} N, beyond its range +-{lim.force:g} N")
        self.trial_state = state
        self.readings = out
        self.trial_time = time_next
        self.trial_command = (d, v, a)
        return out

    def commit(self) -> bool:
        """Keep the trial state. Returns whether the rig moved (False: a commit at the committed time)."""
        moved = self.trial_time != self.committed_time
        if moved:
            self.committed_step += 1
        self.committed = self.trial_state.copy()
        self.committed_readings = self.readings.copy()
        self.committed_time = self.trial_time
        return moved

    def force(self) -> float:
        """The force returned to the client for the trial state [N] (see ``report_mass``)."""
        r = self.readings
        if self.report_mass:
            return float(r[READING_INDEX["Fs"]] - self.carried_mass * r[READING_INDEX["xddot_mean"]])
        return float(r[READING_INDEX["Fs"]])

    def mass(self) -> float:
        """The mass reported through getMass [kg]."""
        return self.carried_mass if self.report_mass else 0.0


#: Backend options that describe the rig (the rest of the substructured backend's are the controller's).
RIG_OPTIONS = (
    "dt", "actuator", "transport_delay", "servo_bandwidth", "servo_damping", "physics_substeps", "force_noise",
    "harmonic3", "harmonic5", "harmonic7", "encoder_resolution", "lvdt_resolution", "lvdt_noise", "stroke", "seed",
)  # fmt: skip
#: Options of a site only.
SITE_OPTIONS = ("report_mass", "velocity_limit", "force_limit")
#: A site's defaults where they differ from the in-process backend's: the client compensates nothing
#: unless told, so the actuator is ideal; the odd harmonics follow the forcing, which a site does not know.
SITE_DEFAULTS = {"actuator": "ideal", "harmonic3": "0", "harmonic5": "0", "harmonic7": "0"}


def rig_from_options(
    options: dict[str, str], params: ModelParams, theta0: float = 0.1, thetadot0: float = 0.0
) -> tuple[SiteRig, dict]:
    """A :class:`SiteRig` from ``-B KEY=VALUE`` strings, and its full configuration (JSON-able).

    Raises :class:`ConfigError` naming an option that is not the rig's (a
    controller option such as ``predictor_order`` belongs to the client).
    """
    from ..backends import make_backend
    from ..backends._base import _to_bool

    unknown = sorted(set(options) - set(RIG_OPTIONS) - set(SITE_OPTIONS))
    if unknown:
        raise ConfigError(
            f"-B {unknown[0]}: not an option of the rig; a site accepts {', '.join(RIG_OPTIONS + SITE_OPTIONS)} "
            "(prediction and filtering belong to the client's controller)"
        )
    rig_opts = SITE_DEFAULTS | {k: v for k, v in options.items() if k in RIG_OPTIONS}
    backend = make_backend("substructured", **rig_opts)
    try:
        report_mass = _to_bool(options.get("report_mass", "true"))
    except ValueError:
        raise ConfigError(f"-B report_mass={options['report_mass']!r}: give true or false") from None
    limits = {}
    for key, field_name in (("velocity_limit", "velocity"), ("force_limit", "force")):
        if key in options:
            try:
                limits[field_name] = float(options[key])
            except ValueError:
                raise ConfigError(f"-B {key}={options[key]!r} is not a number") from None
    rig_limits = RigLimits(stroke=backend.stroke, **limits)
    rig = SiteRig(backend, params, theta0, thetadot0, rig_limits, report_mass)
    config = {
        "params": params.to_dict(),
        "rig": backend.options(),
        "limits": dataclasses.asdict(rig_limits),
        "report_mass": report_mass,
        "carried_mass_kg": rig.carried_mass,
        "initial": {"theta0": theta0, "thetadot0": thetadot0},
    }
    return rig, config
