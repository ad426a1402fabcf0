"""Shooting on the substructured loop's own tick map: periodic orbits of the hybrid test (issue 32).

With its noise off, the simulated substructuring test
(:class:`~pendsweep.backends.substructured.SubstructuredBackend`) is a
deterministic map from one controller tick to the next: numerical model,
predictor history, command delay line, servo, platform, pendulum and the
load cell's momentum. ``n`` ticks make one forcing period, so ``P^k`` maps
the loop's whole state at forcing phase 0 to the state ``k`` periods later
and a ``k``-periodic orbit of the hybrid test is a zero of ``P^k(x) - x``,
exactly as for the emulated system (:mod:`.shooting`); the generic
continuation (:mod:`.core`) continues it unchanged.

What is continued
-----------------
The *live* state: every slot of the loop's state vector that the next ticks
read, i.e. all but the tick counter and the instability monitor's two past
positions (read only by the monitor), the command slopes with the servo
actuator (read only by the Hermite actuators), the ``y*`` history without
prediction, and the filter registers and filtered-force history when the
force path does not use them. A slot that is never read would be a
multiplier exactly 1 of the monodromy and hide every fold.

Monodromy
---------
``dP^k/dx`` by central finite differences over the live slots, each
perturbed by :data:`FD_STEP` times its scale: the loop has five nested
integrators, a delay line and a predictor, and variational equations of
all of them would duplicate the kernel. The error of a central difference
is ``O(h^2)`` truncation plus ``O(eps/h)`` round-off, about 1e-9 relative
here, far below the continuation's tolerances. It costs ``2 m`` loop runs
over ``k`` periods for ``m`` live slots (29 with the defaults, 10 ms delay).

Smoothing (what the record says)
--------------------------------
The tick map must be differentiable:

* the load cell's and LVDT's noise are zero (a deterministic map);
* the encoder and LVDT quantisation are off (exact sensors);
* the pendulum's Coulomb and ``b3`` damping sign is ``tanh(theta' / eps)``
  at each rig substep instead of the held signum (``--eps``, as for the
  emulated system);
* the servo's load-cell harmonics are kept: they repeat every forcing period
  and are smooth;
* the stroke limit and the high-frequency monitor still stop a run (a failed
  evaluation, retried with a smaller step).

:func:`smoothed_backend` makes this backend and :func:`smoothing_record`
says what it changed; the continuation document stores both.

Continued parameters
--------------------
Any model parameter, and the backend's continuous transfer-system options
(:data:`LOOP_PARAMETERS`). ``n`` ticks per period and the delay line's
length are fixed at the start (the longest delay of the interval), so the
map and its state space are continuous in every parameter: continuing
``fe`` changes the controller step ``dt = 1/(fe n)``, as the emulated
shooting does.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...backends.substructured import SubstructuredBackend
from ...errors import ConfigError
from ...kernels import N_RECORD_COLUMNS, STATUS_DIVERGED, STATUS_OK, wrap_angle
from ...kernels._substructured import (
    S_P_TH,
    S_P_X,
    S_P_XD,
    S_THETA,
    S_THETADOT,
    S_TICKS,
    S_X,
    S_XDOT,
    S_XPREV1,
    S_XPREV2,
    S_Y,
    S_YDOT,
    LoopSettings,
    state_offsets,
    substructured_loop,
)
from ...model.params import PARAM_SPECS, ModelParams
from .problem import Evaluation
from .shooting import SECTION, OrbitDiverged, OrbitInfo

#: Backend options that can be continued, with their unit: the transfer system and the prediction.
LOOP_PARAMETERS = {
    "transport_delay": "s",
    "servo_bandwidth": "Hz",
    "servo_damping": "-",
    "tau_hat": "s",
}

#: Sensor options a continuation switches off (a deterministic, smooth map).
SMOOTHED_OFF = ("force_noise", "lvdt_noise", "encoder_resolution", "lvdt_resolution")

#: Relative finite-difference step of the monodromy (times each slot's scale).
FD_STEP = 1e-6
#: Precision of a multiplier of the finite-difference monodromy (truncation h^2 plus round-off eps/h):
#: the floor below which Newton on a curve's defining system cannot go (:mod:`.curves`).
MULTIPLIER_PRECISION = 1e-8


def smoothed_backend(backend: SubstructuredBackend) -> SubstructuredBackend:
    """``backend`` with its noise and quantisation off (:data:`SMOOTHED_OFF`); refuses a remote rig."""
    if backend.rig:
        raise ConfigError(
            f"a remote rig (rig = {backend.rig}) cannot be continued: its tick map is the hardware's; "
            "continue the simulated loop (drop -B rig) with the rig's identified options"
        )
    return dataclasses.replace(backend, **{name: 0.0 for name in SMOOTHED_OFF})


def smoothing_record(backend: SubstructuredBackend, eps: float) -> dict[str, object]:
    """What the continuation changed in ``backend`` to make its tick map smooth (stored with the result)."""
    changed = {name: getattr(backend, name) for name in SMOOTHED_OFF if getattr(backend, name) != 0.0}
    return {
        "switched_off": changed,
        "damping_sign": f"tanh(theta'/{eps:g}) per rig substep" if eps > 0 else "signum held per substep",
        "kept": "servo harmonics (periodic), stroke limit and high-frequency monitor (stop a run)",
    }


def live_slots(backend: SubstructuredBackend, settings: LoopSettings) -> np.ndarray:
    """Indices of the state slots the loop's next ticks read (module docstring)."""
    o_cmd, o_cmdd, o_yh, o_fh, o_z, end = state_offsets(settings.n_cmd, settings.w_pred.shape[0], settings.sos.shape[0])
    slots = [S_Y, S_YDOT, S_THETA, S_THETADOT, S_X, S_XDOT, S_P_XD, S_P_X, S_P_TH]
    slots += range(o_cmd, o_cmdd)
    if backend.actuator != "servo":
        slots += range(o_cmdd, o_yh)
    if settings.use_pred:
        slots += range(o_yh, o_fh)
    if settings.use_force_pred:
        slots += range(o_fh, o_z)
    if settings.use_filter:
        slots += range(o_z, end)
    return np.array(slots, dtype=np.int64)


def slot_scales(settings: LoopSettings, params: ModelParams, length: int) -> np.ndarray:
    """Characteristic size of every state slot: lengths in ``l``, rates in ``l w_e``, angles in 1 rad, forces in ``m g``."""
    l, w = params.l, params.omega_e
    o_cmd, o_cmdd, o_yh, o_fh, o_z, end = state_offsets(settings.n_cmd, settings.w_pred.shape[0], settings.sos.shape[0])
    scale = np.full(length, l)  # positions: y*, x, commands, y* history
    scale[[S_YDOT, S_XDOT, S_P_XD]] = l * w
    scale[o_cmdd:o_yh] = l * w
    scale[S_THETA] = 1.0
    scale[[S_THETADOT, S_P_TH]] = w
    scale[o_fh:end] = params.m * params.g
    scale[S_TICKS] = 1.0
    return scale


class LoopShooting:
    """The ``k``-period map of the noise-free substructured loop as a :class:`~pendsweep.analysis.continuation.problem.MapProblem`.

    Parameters
    ----------
    backend : SubstructuredBackend
        The loop (made smooth by :func:`smoothed_backend`; a noisy one is refused).
    params : ModelParams
        The model; ``parameter`` is replaced by the continuation value.
    parameter : str
        A model parameter or a key of :data:`LOOP_PARAMETERS`.
    period : int
        ``k``, forcing periods per map application.
    eps : float
        Damping-sign smoothing [rad/s] (0: the held signum, non-smooth with b1 > 0).
    lam_scale : float
        Characteristic size of the parameter [its unit].
    steps, n_cmd : int or None
        Ticks per period and delay-line length; default from the backend at
        ``params`` (fixed for the whole continuation).
    """

    def __init__(
        self,
        backend: SubstructuredBackend,
        params: ModelParams,
        parameter: str,
        period: int = 1,
        eps: float = 1e-3,
        lam_scale: float = 1.0,
        steps: int | None = None,
        n_cmd: int | None = None,
    ):
        if backend.noisy:
            raise ConfigError("the loop must be noise-free to be continued; make it with smoothed_backend()")
        if parameter not in PARAM_SPECS and parameter not in LOOP_PARAMETERS:
            raise ConfigError(
                f"cannot continue the loop in {parameter!r}; choose a model parameter or one of "
                f"{', '.join(LOOP_PARAMETERS)}"
            )
        backend.validate(params)
        self.backend = backend
        self.params = params
        self.parameter = parameter
        self.period = int(period)
        self.eps = float(eps)
        self.lam_scale = float(lam_scale)
        self.steps = int(steps) if steps is not None else backend.steps_per_period(params)
        self.n_cmd = int(n_cmd) if n_cmd is not None else backend.n_cmd
        settings = self.settings_at(self._lam0())
        self.length = state_offsets(self.n_cmd, settings.w_pred.shape[0], settings.sos.shape[0])[5]
        self.live = live_slots(backend, settings)
        self.scale = slot_scales(settings, params, self.length)[self.live]
        self.theta = int(np.flatnonzero(self.live == S_THETA)[0])
        self._last: tuple[float, LoopSettings, np.ndarray] | None = None
        self.multiplier_precision = MULTIPLIER_PRECISION

    def _lam0(self) -> float:
        source = self.backend if self.parameter in LOOP_PARAMETERS else self.params
        value = getattr(source, self.parameter)
        return self.backend.horizon(self.params) if value is None else float(value)

    def with_period(self, period: int) -> LoopShooting:
        return LoopShooting(
            self.backend, self.params, self.parameter, period, self.eps, self.lam_scale, self.steps, self.n_cmd
        )

    def at(self, parameter: str, value: float) -> LoopShooting:
        """The same problem with ``parameter`` (model or loop) fixed at ``value``."""
        backend, params = self.backend, self.params
        if parameter in LOOP_PARAMETERS:
            backend = dataclasses.replace(backend, **{parameter: value})
        else:
            params = params.replace(**{parameter: value})
        return LoopShooting(
            backend, params, self.parameter, self.period, self.eps, self.lam_scale, self.steps, self.n_cmd
        )

    # -- the map -----------------------------------------------------------------------
    def settings_at(self, lam: float) -> LoopSettings:
        """The kernel's settings at parameter value ``lam`` (ParameterError/ConfigError outside its range)."""
        backend, params = self.backend, self.params
        if self.parameter in LOOP_PARAMETERS:
            if not (math.isfinite(lam) and lam >= 0.0 and (lam > 0.0 or self.parameter != "servo_bandwidth")):
                raise ConfigError(f"{self.parameter} = {lam!r} must be a finite number >= 0")
            backend = dataclasses.replace(backend, **{self.parameter: lam})
        else:
            params = params.replace(**{self.parameter: lam})
        dt = 1.0 / (params.fe * self.steps)
        # The backend at the tick actually used (fe continued: dt = 1/(fe n) drifts), so that its matched
        # prediction horizon and hold delay are those of this tick, as a sweep at this fe would have them.
        backend = dataclasses.replace(backend, dt=dt)
        if self.n_cmd < int(math.ceil(backend.transport_delay / dt)) + 3:
            raise ConfigError(
                f"transport_delay = {backend.transport_delay:g} s is longer than the delay line of "
                f"{self.n_cmd} ticks fixed at the start; start the continuation at the longest delay"
            )
        settings = backend.loop_settings(params, dt)
        return settings._replace(steps_per_period=self.steps, n_cmd=self.n_cmd, sign_eps=self.eps)

    def params_at(self, lam: float) -> ModelParams:
        return self.params if self.parameter in LOOP_PARAMETERS else self.params.replace(**{self.parameter: lam})

    def full_state(self, x: np.ndarray) -> np.ndarray:
        """The loop's whole state with the live slots ``x`` (the slots no tick reads: zeros, or consistent with ``x``)."""
        s = np.zeros(self.length)
        s[self.live] = x
        s[S_TICKS] = 0.0
        s[S_XPREV1] = s[S_XPREV2] = s[S_X]
        return s

    def from_section(self, section: np.ndarray) -> np.ndarray:
        """Live slots of the loop at rest on an emulated section ``(y, ydot, theta, thetadot)`` (histories constant)."""
        y, ydot, theta, thetadot = (float(v) for v in section)
        s = np.zeros(self.length)
        o_cmd, o_cmdd, o_yh, o_fh, o_z, _ = state_offsets(self.n_cmd, self.backend.predictor_points,
                                                          self.backend.filter_order)  # fmt: skip
        s[[S_Y, S_YDOT, S_THETA, S_THETADOT, S_X, S_XDOT]] = y, ydot, theta, thetadot, y, ydot
        s[S_P_XD], s[S_P_X], s[S_P_TH] = ydot, y, thetadot * math.sin(theta)
        s[o_cmd:o_cmdd], s[o_cmdd:o_yh], s[o_yh:o_fh] = y, ydot, y
        return s[self.live]

    def section(self, x: np.ndarray) -> np.ndarray:
        """``(y*, y*', theta, theta')`` of the live state ``x`` (the emulated system's section)."""
        return self.full_state(x)[[S_Y, S_YDOT, S_THETA, S_THETADOT]]

    def _advance(self, x: np.ndarray, settings: LoopSettings, kernel: np.ndarray, records: np.ndarray) -> np.ndarray:
        s = self.full_state(x)
        none = np.zeros(self.period * self.steps)
        status, _ = substructured_loop(s, kernel, settings, none, none, 0, records, np.empty((0, 15)), 1)
        if status != STATUS_OK:
            why = (
                "ran away"
                if status == STATUS_DIVERGED
                else "is unstable here (its stroke or high-frequency monitor tripped)"
            )
            raise OrbitDiverged(f"the loop {why} at this {self.parameter}: no orbit of the hybrid test to continue")
        return s[self.live]

    def _settings_and_kernel(self, lam: float) -> tuple[LoopSettings, np.ndarray]:
        """The kernel's settings and parameter vector at ``lam``, kept for the last value asked: a curve's
        gradient evaluates the map some hundred times at one parameter value."""
        if self._last is None or self._last[0] != lam:
            self._last = (lam, self.settings_at(lam), self.params_at(lam).kernel_array())
        return self._last[1], self._last[2]

    def evaluate(self, x: np.ndarray, lam: float, tangent: bool = True) -> Evaluation:
        """``P^k(x) - x`` (theta wrapped), the finite-difference monodromy (when ``tangent``) and the records."""
        settings, kernel = self._settings_and_kernel(lam)
        records = np.empty((self.period, N_RECORD_COLUMNS))
        x = np.asarray(x, dtype=np.float64)
        image = self._advance(x, settings, kernel, records)
        residual = image - x
        residual[self.theta] = wrap_angle(residual[self.theta])
        jacobian = None
        if tangent:
            jacobian = np.empty((x.size, x.size))
            scratch = np.empty((self.period, N_RECORD_COLUMNS))
            for j in range(x.size):
                h = FD_STEP * self.scale[j]
                up, down = x.copy(), x.copy()
                up[j] += h
                down[j] -= h
                column = self._advance(up, settings, kernel, scratch) - self._advance(down, settings, kernel, scratch)
                column[self.theta] = wrap_angle(column[self.theta])
                jacobian[:, j] = column / (2.0 * h)
        return Evaluation(residual, jacobian, OrbitInfo(records, math.nan))

    def _section_scale(self) -> np.ndarray:
        w = self.params.omega_e
        return np.array([self.params.l, self.params.l * w, 1.0, w])

    def subperiod_distance(self, x: np.ndarray, info: OrbitInfo) -> float:
        """Scaled max-norm distance between the section of ``x`` and the one after ``k/2`` periods (inf for odd ``k``).

        Sections ``(y*, y*', theta, theta')`` as for the emulated system: the
        rest of the loop follows them on an orbit.
        """
        if self.period % 2:
            return math.inf
        d = info.records[self.period // 2 - 1, SECTION] - self.section(x)
        d[2] = wrap_angle(d[2])
        return float(np.abs(d / self._section_scale()).max())

    def image_distance(self, info: OrbitInfo, y: np.ndarray) -> float:
        """Scaled 2-norm distance from the section of ``y`` to the nearest section after 1 ... k-1 periods."""
        d = info.records[: self.period - 1][:, SECTION] - self.section(y)
        if not d.size:
            return math.inf
        d[:, 2] = (d[:, 2] + math.pi) % (2.0 * math.pi) - math.pi
        return float(np.sqrt(((d / self._section_scale()) ** 2).sum(axis=1)).min())
