"""A simulated real-time dynamic substructuring test (sections 2.2-2.6 of the paper).

The mass-spring-damper is the numerical model, Eq. (3), integrated by the
controller; the pendulum on its platform is the physical substructure (a
virtual rig integrated at a finer step), the actuator is the transfer
system, and a load cell feeds the interface force back. The loop itself is
:func:`pendsweep.kernels._substructured.substructured_loop`; its module
docstring gives the exact order of operations within one controller tick.

Timing conventions (used by the stability analysis of this loop)
-----------------------------------------------------------------
* Controller step ``dt`` (default 1 ms), adjusted like the emulated backend to
  a whole number ``n`` of ticks per forcing period: ``dt = 1/(fe n)``.
* Numerical model: RK4 over one tick with ``F = F_e(t) - F_fb``, ``F_e`` exact
  at the stages and ``F_fb`` the force sampled at the tick's start and held.
* Command ``c_k`` = ``y*`` predicted by ``tau_hat`` from the samples up to
  ``y*_k``. The servo sees it through a zero-order hold that writes ``c_k`` at
  ``t_k`` and keeps it until ``t_k+1`` (an average delay of ``dt/2``), after a
  transport delay ``tau``, then ``G(s) = ws^2/(s^2 + 2 zeta ws s + ws^2)``:
  ``T(s) = exp(-s tau) G(s)`` on the held command.
* Actuator ``"delay"``: ``x(t) = c(t - tau)`` with ``c(t)`` the cubic Hermite
  interpolant of the command samples and their slopes (no hold, no lag), the
  fixed-delay model of Eq. (6). ``"ideal"``: the same with ``tau = 0``; with
  no prediction ``x`` then follows ``y*`` exactly (the consistency limit).
* Total effective delay at frequency ``f`` (:func:`effective_delay`):
  ``tau + dt/2 + arg(1/G(j 2 pi f)) / (2 pi f)`` for the servo (transport +
  hold + servo phase lag), ``tau`` for ``"delay"``, 0 for ``"ideal"``. The
  force path's own hold (``dt/2``) and the numerical model's RK4 are not
  counted: the total describes how ``x`` lags ``y*``, which is what the
  predictor compensates and what the synchronisation error measures. With
  the defaults (30 Hz, zeta 0.7, tau 10 ms, dt 1 ms) it is 17.94 ms at
  2.2 Hz and 17.95 ms at 2.5 Hz, the paper's "approximately 18 ms".

Noise is drawn outside the kernel from ``numpy.random.default_rng([seed,
ticks])`` where ``ticks`` (``state[6]``) counts the controller ticks already
run from the state's initial condition, so a branch is reproducible whatever
the thread scheduling and a continued state never replays the same noise.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from ..errors import ConfigError
from ..kernels import N_RECORD_COLUMNS
from ..kernels._actuator import ACT_HERMITE, ACT_SERVO
from ..kernels._substructured import (
    N_TRACE_COLUMNS,
    S_P_TH,
    S_P_X,
    S_P_XD,
    S_TICKS,
    S_XPREV1,
    S_XPREV2,
    TRACE_COLUMNS,
    LoopSettings,
    state_offsets,
    substructured_loop,
)
from ..model.loop import (
    ACTUATORS,
    MAX_PREDICTOR_ORDER,
    design_force_filter,
    effective_delay,
    filter_delay,
    prediction_horizon,
    predictor_weights,
)
from ..model.params import ENCODER_RESOLUTION, ModelParams
from ._base import BackendBase, PointRun, register
from .status import Status
from .transports import rig_transport

if TYPE_CHECKING:  # pandas (0.3 s) is imported by the functions that build frames, not by importing this module
    import pandas as pd

#: Options of the virtual rig, refused with a remote one (they are the site's to set).
REMOTE_RIG_OPTIONS = (
    "physics_substeps", "force_noise", "harmonic3", "harmonic5", "harmonic7", "encoder_resolution",
    "lvdt_resolution", "lvdt_noise",
)  # fmt: skip
#: Instability test: rms of x'' at the controller rate above this [m/s^2] ...
HF_ACCEL_FLOOR = 2.0
#: ... and above this multiple of a pure forcing-frequency motion's, for 2 periods in a row.
HF_RATIO = 10.0


@register
@dataclass(frozen=True)
class SubstructuredBackend(BackendBase):
    """Simulated real-time substructuring test of the pendulum-oscillator.

    The numerical model is ``M1 y*'' + C1 y*' + K y* = F_e - F_s`` with
    ``M1 = M - M2`` and ``C1 = C - C2`` (Table IV: ``M2 = 0.9 kg``,
    ``C2 = 10 kg/s``); the rig is the pendulum on the platform ``(M2, C2)``
    driven at the pivot by the actuator. Records hold ``y*`` and the encoder
    angle ``theta_x`` (quantised), as in Fig. 11; ``thetadot_sec`` is the true
    rate. State: ``(y*, y*', theta, theta', x, x', ticks, x_k-1, x_k-2,
    x', x, theta' sin(theta) at the last load-cell sample,`` command delay
    line, command slopes, ``y*`` history, filtered-force history, filter
    registers ``)``; see the kernel module.

    Attributes
    ----------
    dt : float
        Controller step [s] (default 1 ms), adjusted to whole ticks per period.
    physics_substeps : int
        Rig RK4 substeps per controller step (default 10: 0.1 ms).
    actuator : {"servo", "delay", "ideal"}
        Transfer system model (see the module docstring).
    transport_delay : float
        Pure delay before the servo [s] (default 10 ms; total 17.9 ms at 2.2 Hz).
    servo_bandwidth : float
        Servo natural frequency [Hz] (default 30).
    servo_damping : float
        Servo damping ratio (default 0.7).
    predictor_order : int
        Polynomial order 0-4 of the forward prediction of ``y*``; -1: none (default 1).
    predictor_points : int
        Samples ``N >= order + 1`` in the least-squares fit (default 5).
    tau_hat : float or None
        Prediction horizon [s]; None (default): matched, the total effective
        delay at the forcing frequency, :meth:`effective_delay`.
    force_filter : bool
        Band-pass the measured force (default off).
    filter_low, filter_high : float
        Band edges [Hz] of the Butterworth band-pass (default 1-3.6 Hz: at
        2.2 Hz its phase is -0.215 rad, close to the paper's Fig. 7 example).
    filter_order : int
        Butterworth order (the band-pass has twice this many poles; default 1).
        With prediction on, the filtered force is predicted forward by the
        filter's equivalent delay ``-phase(fe) / (2 pi fe)``.
    force_noise : float
        Standard deviation of the load cell's white electrical noise [N] (default 0.1).
    harmonic3, harmonic5, harmonic7 : float
        Amplitudes [N] of the servo vibration at 3, 5, 7 times the forcing
        frequency in the load-cell signal (defaults 0.1, 0.05, 0.03).
    encoder_resolution : float
        Encoder step [rad] (default 0.0013, Table III; 0: exact).
    lvdt_resolution : float
        LVDT quantisation [m] (default 1e-5: 150 mm range on 14 bits).
    lvdt_noise : float
        LVDT noise standard deviation [m] (default 2e-5).
    stroke : float
        Actuator stroke limit [m]: ``|x|`` or ``|y*|`` beyond it stops the point
        as unstable (default 0.075, the LVDT's +-75 mm).
    seed : int
        Seed of the noise (default 0).
    rig : str
        Empty (default): the virtual rig in this process. ``tcp://HOST:PORT``:
        a remote experimental site (``pendsweep site``, or a real rig's
        OpenFresco site) takes the commands and returns its measurements,
        reached through the transport registered for the URL's scheme
        (:mod:`.transports`; ``tcp``: :mod:`pendsweep.hybrid.client`); the transfer-system options then
        only set the prediction horizon, and the sensor options are the site's.
    """

    name: ClassVar[str] = "substructured"
    dt: float = 1e-3
    physics_substeps: int = 10
    actuator: str = "servo"
    transport_delay: float = 0.010
    servo_bandwidth: float = 30.0
    servo_damping: float = 0.7
    predictor_order: int = 1
    predictor_points: int = 5
    tau_hat: float | None = None
    force_filter: bool = False
    filter_low: float = 1.0
    filter_high: float = 3.6
    filter_order: int = 1
    force_noise: float = 0.1
    harmonic3: float = 0.1
    harmonic5: float = 0.05
    harmonic7: float = 0.03
    encoder_resolution: float = ENCODER_RESOLUTION
    lvdt_resolution: float = 1e-5
    lvdt_noise: float = 2e-5
    stroke: float = 0.075
    seed: int = 0
    rig: str = ""

    def __post_init__(self) -> None:
        def need(ok: bool, text: str) -> None:
            if not ok:
                raise ConfigError(text)

        for name in (
            "dt", "transport_delay", "servo_bandwidth", "servo_damping", "filter_low",
            "filter_high", "force_noise", "harmonic3", "harmonic5", "harmonic7",
            "encoder_resolution", "lvdt_resolution", "lvdt_noise", "stroke",
        ):  # fmt: skip
            need(math.isfinite(getattr(self, name)), f"{name} = {getattr(self, name)!r} must be finite")
        need(self.dt > 0, f"dt = {self.dt!r} s must be > 0")
        need(
            self.tau_hat is None or (math.isfinite(self.tau_hat) and self.tau_hat >= 0),
            f"tau_hat = {self.tau_hat!r} s must be a finite delay >= 0 (or None: matched to the effective delay)",
        )
        need(self.physics_substeps >= 1, f"physics_substeps = {self.physics_substeps!r} must be an integer >= 1")
        need(self.actuator in ACTUATORS, f"actuator = {self.actuator!r}; choose one of {', '.join(ACTUATORS)}")
        need(self.transport_delay >= 0, f"transport_delay = {self.transport_delay!r} s must be >= 0")
        need(self.servo_bandwidth > 0, f"servo_bandwidth = {self.servo_bandwidth!r} Hz must be > 0")
        need(self.servo_damping > 0, f"servo_damping = {self.servo_damping!r} must be > 0")
        need(
            -1 <= self.predictor_order <= MAX_PREDICTOR_ORDER,
            f"predictor_order = {self.predictor_order!r}; accepted: -1 (none) or 0..{MAX_PREDICTOR_ORDER}",
        )
        need(
            self.predictor_points >= max(self.predictor_order + 1, 1),
            f"predictor_points = {self.predictor_points!r} must be >= predictor_order + 1 = {self.predictor_order + 1}",
        )
        need(
            0 < self.filter_low < self.filter_high < 0.5 / self.dt,
            f"filter band [{self.filter_low!r}, {self.filter_high!r}] Hz must satisfy 0 < low < high < "
            f"Nyquist {0.5 / self.dt:g} Hz",
        )
        need(1 <= self.filter_order <= 8, f"filter_order = {self.filter_order!r}; accepted 1..8")
        for name in ("force_noise", "harmonic3", "harmonic5", "harmonic7", "encoder_resolution",
                     "lvdt_resolution", "lvdt_noise"):  # fmt: skip
            need(getattr(self, name) >= 0, f"{name} = {getattr(self, name)!r} must be >= 0")
        need(self.stroke > 0, f"stroke = {self.stroke!r} m must be > 0")
        need(self.seed >= 0, f"seed = {self.seed!r} must be an integer >= 0")
        if self.rig:
            rig_transport(self.rig)
            defaults = {f.name: f.default for f in dataclasses.fields(self)}
            for name in REMOTE_RIG_OPTIONS:
                need(
                    getattr(self, name) == defaults[name],
                    f"{name} describes the rig, which is remote (rig = {self.rig}): set it at the site "
                    f"(pendsweep site -B {name}=...)",
                )

    @classmethod
    def check_options(cls, options: dict) -> None:
        """Refuse rig options given with a remote rig, even at their default values (they are the site's)."""
        if options.get("rig"):
            given = [name for name in REMOTE_RIG_OPTIONS if name in options]
            if given:
                raise ConfigError(
                    f"{given[0]} describes the rig, which is remote (rig = {options['rig']}): set it at the site "
                    f"(pendsweep site -B {given[0]}=...)"
                )

    # -- contract -----------------------------------------------------------------
    @property
    def restartable(self) -> bool:
        """A remote rig starts every run from the site's own initial state (one controller at a time)."""
        return not self.rig

    @property
    def noisy(self) -> bool:
        """Whether records carry noise: a remote rig's sensors always do; the virtual rig's unless all are exact.

        The load cell's noise drives the numerical model (process noise on
        ``y*``), the encoder quantises ``theta``, the LVDT's noise reaches the
        command through the loop. The servo's harmonics repeat every forcing
        period and are no noise to a stroboscopic section.
        """
        sources = (self.force_noise, self.encoder_resolution, self.lvdt_resolution, self.lvdt_noise)
        return bool(self.rig) or any(v > 0 for v in sources)

    def validate(self, params: ModelParams) -> None:
        if params.M1 <= 0 or params.C1 < 0:
            raise ConfigError(
                f"the substructured split needs M1 = M - M2 > 0 and C1 = C - C2 >= 0; got "
                f"M1 = {params.M1:g} kg (M = {params.M:g}, M2 = {params.M2:g}) and "
                f"C1 = {params.C1:g} kg/s (C = {params.C:g}, C2 = {params.C2:g})"
            )
        if 1.0 / params.fe < self.dt:
            raise ConfigError(f"forcing period 1/fe = {1 / params.fe:g} s is shorter than dt = {self.dt:g} s")
        if self.force_filter and not (self.filter_low < params.fe < self.filter_high):
            raise ConfigError(
                f"forcing frequency fe = {params.fe:g} Hz lies outside the force filter's band "
                f"[{self.filter_low:g}, {self.filter_high:g}] Hz"
            )

    def step(self, params: ModelParams) -> float:
        """Controller step actually used [s]."""
        return 1.0 / (params.fe * self.steps_per_period(params))

    @property
    def n_cmd(self) -> int:
        """Length of the command delay line (covers the transport delay with margin)."""
        return int(math.ceil(1.1 * self.transport_delay / self.dt)) + 4

    def state_length(self) -> int:
        return state_offsets(self.n_cmd, self.predictor_points, self.filter_order)[5]

    def initial_state(self, params, y, ydot, theta, thetadot) -> np.ndarray:
        """Rest of the loop consistent with ``y* = x = y`` (histories constant, filter empty)."""
        o_cmd, o_cmdd, o_yh, o_fh, o_z, length = state_offsets(self.n_cmd, self.predictor_points, self.filter_order)
        s = np.zeros(length)
        s[:6] = (y, ydot, theta, thetadot, y, ydot)  # y*, y*', theta, theta', x, x'
        s[S_XPREV1] = s[S_XPREV2] = y
        s[S_P_XD], s[S_P_X], s[S_P_TH] = ydot, y, thetadot * math.sin(theta)
        s[o_cmd:o_cmdd] = y
        s[o_cmdd:o_yh] = ydot
        s[o_yh:o_fh] = y
        return s

    # -- delays -------------------------------------------------------------------
    def effective_delay(self, frequency: float) -> float:
        """Total effective delay [s] of ``x`` behind ``y*`` at ``frequency`` [Hz]."""
        return effective_delay(
            self.actuator, self.transport_delay, self.servo_bandwidth, self.servo_damping, self.dt, frequency
        )

    def horizon(self, params: ModelParams) -> float:
        """Prediction horizon ``tau_hat`` [s] used at these parameters."""
        return prediction_horizon(self.tau_hat, self.effective_delay(params.fe))

    def filter_sos(self, params: ModelParams, dt: float | None = None) -> np.ndarray:
        """The force filter's second-order sections at controller step ``dt`` [s] (default :meth:`step`)."""
        dt = self.step(params) if dt is None else dt
        return design_force_filter(self.filter_low, self.filter_high, self.filter_order, dt)

    def filter_delay(self, params: ModelParams, dt: float | None = None) -> float:
        """Equivalent delay [s] of the force filter at the forcing frequency (0 when off)."""
        if not self.force_filter:
            return 0.0
        dt = self.step(params) if dt is None else dt
        return filter_delay(self.filter_sos(params, dt), params.fe, dt)

    def loop_settings(self, params: ModelParams, dt: float | None = None) -> LoopSettings:
        """The kernel's :class:`LoopSettings` for these parameters (controller, transfer system, rig, sensors).

        ``dt`` [s] overrides the controller step (an experimental site runs at its client's step).
        """
        dt = self.step(params) if dt is None else dt
        use_pred = self.predictor_order >= 0
        order = max(self.predictor_order, 0)
        w, wd = predictor_weights(order, self.predictor_points, self.horizon(params), dt)
        wf, _ = predictor_weights(order, self.predictor_points, self.filter_delay(params, dt), dt)
        return LoopSettings(
            M2=float(params.M2),
            C2=float(params.C2),
            alpha=float(params.alpha),
            fe=float(params.fe),
            steps_per_period=int(self.steps_per_period(params)),
            substeps=int(self.physics_substeps),
            actuator=ACT_SERVO if self.actuator == "servo" else ACT_HERMITE,
            tau=float(self.transport_delay if self.actuator != "ideal" else 0.0),
            ws=2.0 * math.pi * self.servo_bandwidth,
            zeta=float(self.servo_damping),
            n_cmd=int(self.n_cmd),
            use_pred=bool(use_pred),
            w_pred=w,
            wd_pred=wd,
            use_filter=bool(self.force_filter),
            # Without the filter its sections only size the (unused) state slots: no design needed.
            sos=self.filter_sos(params, dt) if self.force_filter else np.zeros((self.filter_order, 6)),
            use_force_pred=bool(self.force_filter and use_pred),
            w_force=wf,
            enc_res=float(self.encoder_resolution),
            lvdt_res=float(self.lvdt_resolution),
            harmonics=np.array([self.harmonic3, self.harmonic5, self.harmonic7]),
            stroke=float(self.stroke),
            hf_ratio=HF_RATIO,
            hf_accel=HF_ACCEL_FLOOR,
            sign_eps=0.0,
        )

    # -- running ------------------------------------------------------------------
    def _run(self, params, state, transient, n_rec, trace_rows, stride):
        self.validate(params)
        state = np.ascontiguousarray(state, dtype=np.float64).copy()
        if state.shape != (self.state_length(),):
            raise ConfigError(
                f"state of length {state.shape} does not fit these backend options "
                f"(expected {self.state_length()}); start from initial_state"
            )
        if self.rig:
            return rig_transport(self.rig).run(self, params, state, transient, n_rec, trace_rows, stride)
        n = self.steps_per_period(params)
        ticks = (transient + n_rec) * n
        rng = np.random.default_rng([self.seed, int(state[S_TICKS])])
        noise_f = rng.standard_normal(ticks) * self.force_noise
        noise_x = rng.standard_normal(ticks) * self.lvdt_noise
        records = np.full((n_rec, N_RECORD_COLUMNS), np.nan)
        trace = np.full((trace_rows, N_TRACE_COLUMNS), np.nan)
        settings = self.loop_settings(params)
        code, done = substructured_loop(
            state, params.kernel_array(), settings, noise_f, noise_x, transient, records, trace, stride
        )
        return code, int(done), state, records, trace, None

    def run_point(self, params, state, transient_periods, record_periods) -> PointRun:
        code, done, state, records, _, timing = self._run(params, state, transient_periods, record_periods, 0, 1)
        return PointRun(records, state, Status.from_code(code), done, timing)

    def trace(self, params, state, periods, stride=1) -> pd.DataFrame:
        """Time series of ``periods`` forcing periods, every ``stride``-th tick.

        Columns (SI): ``t, Fe, y`` (= y*), ``ydot, command`` (the held command
        ``c_k``), ``x, xdot`` (true actuator), ``x_meas`` (LVDT), ``theta``
        (encoder, theta_x), ``theta_true, thetadot, Fs`` (load cell), ``Fs_true``
        (the load cell without noise: Eq. (4) averaged over the last tick),
        ``F_fb`` (force fed to the model) and ``sync_error``
        (``y* - x_meas``). Rows after an instability are dropped; the status is
        in ``df.attrs["status"]``.
        """
        n = self.steps_per_period(params)
        rows = (periods * n + stride - 1) // stride
        code, done, _, _, trace, _ = self._run(params, state, periods, 0, rows, stride)
        import pandas as pd

        df = pd.DataFrame(trace, columns=list(TRACE_COLUMNS)).dropna(subset=["t"]).reset_index(drop=True)
        df.attrs["status"] = Status.from_code(code).value
        df.attrs["periods_done"] = done
        return df
