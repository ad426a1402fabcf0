"""The parts of a substructured test replayed each on its own: physical substructure and numerical model.

The closed-loop replay of a substructured record (:class:`~.whole.Replay`)
runs command, actuator, specimen and force feedback together, so an error in
one part is seen through all of them and any parameter may absorb it: a servo
that lags is fitted as a lighter numerical mass. A record holds what is needed
to open the loop at both of its interfaces:

:class:`PhysicalReplay` (kind ``physical``)
    The specimen (the pendulum on its platform) driven by the platform's
    motion, compared with the encoder ``theta`` and the load cell ``Fs``. The
    motion is the identified transfer model's (:mod:`..identify.transfer`) response to
    the command: the LVDT reading, denoised through a model checked against
    it, with exact derivatives. Candidates: the pendulum's (length, friction,
    damping, drag, encoder zero), the platform's mass and damping, and the
    load cell's gain.
:class:`NumericalReplay` (kind ``numerical``)
    The numerical model driven by the forces the controller was given (the
    recorded ``Fe`` and the load-cell reading ``Fs``, or the fed-back force
    ``F_fb`` when the record has it), compared with its own output: ``y_star``
    when recorded, else the command ``y_cmd``, which a forward predictor sets
    ahead of ``y*`` by a lead fitted as a nuisance (``command_lead`` [s]); the
    controller's integrator (RK4 or central difference) is chosen by the
    nominal model's error on that exact output. Candidates: the oscillator's
    mass, damping, stiffness, hardening and the forcing gain.

Each part is diagnosed with the same fits, cross-validation and tests as a
whole record (:func:`pendsweep.measured.diagnose.fit.diagnose`), and only with the
causes that belong to it, so no numerical-model parameter can be named for an
actuator or specimen effect. The controller's own output is exact (no sensor
noise), so the numerical part's noise floor is the model-form error of the
controller's conventions this replay does not know (integrator, force hold,
predictor): :data:`CONVENTION_FLOOR` of the compared channel's spread.
"""

from __future__ import annotations

import math

import numpy as np

from ....kernels._measured import numerical_trace, platform_trace
from ....model.params import kernel_vector
from ...records import Record
from ..effects import nominal_values
from ..signals import midpoint_values, smoothed
from .whole import DEFAULT_HORIZON, FOLDS, MAX_STEP, Replay, _cut

#: Noise floor of the numerical part: the relative model-form error that controller conventions
#: unknown to the replay leave (chosen on the calibration seeds; see docs/measured-data.md).
CONVENTION_FLOOR = 5e-3
#: Seconds at a record's start that are not compared (the transfer model's servo settling).
SETTLE = 0.1
#: Integrators the numerical replay knows; the controller's is chosen by the nominal model's error.
INTEGRATORS = ("rk4", "central")
#: Largest forward-predictor lead the numerical replay fits [s].
MAX_LEAD = 0.2


class PhysicalReplay(Replay):
    """The physical substructure of a substructured record, driven by the platform's motion.

    Parameters
    ----------
    record : Record
        A ``substructured`` or ``rig`` record with ``theta`` and ``Fs``.
    motion : ndarray
        Platform x [m], x' [m/s], x'' [m/s^2] on ``2 * substeps`` rows per
        sample (:meth:`pendsweep.measured.diagnose.identify.transfer.TransferProblem.motion`).
    substeps : int
        Pendulum RK4 steps per sample.
    horizon : float, optional
        Segment length [s] (default 4).
    folds : int
        Cross-validation folds.
    """

    def __init__(
        self, record: Record, motion: np.ndarray, substeps: int, horizon: float | None = None, folds: int = FOLDS
    ):
        self.kind = "physical"
        self._compare(record, ("theta", "Fs"), folds, max(1, int(math.ceil(SETTLE / record.dt))))
        self.nominal = nominal_values(record.params, record.tau)
        self.initial_guess = {}
        self.fits_initial_state = False
        self.motion = np.ascontiguousarray(motion)
        self.substeps = int(substeps)
        self.point = record.sampling("load_cell") == "point"
        self.kinked = record.sampling("command") != "smooth"
        self.per_sample = 2 * self.substeps
        self.horizon = DEFAULT_HORIZON if horizon is None else float(horizon)
        self.segments = _cut(self.start, self.n, max(20, int(round(self.horizon / self.dt))))
        theta, thetadot = smoothed(record.channel("theta"), self.dt)
        # Each segment starts one sample early: the load cell's first reading needs the step before it.
        starts = np.array([s - 1 for s, _ in self.segments])
        self.states0 = np.stack([theta[starts], thetadot[starts]], axis=1)

    def simulate(self, values: dict[str, float], stop: int | None = None) -> dict[str, np.ndarray]:
        stop = self.n if stop is None else stop
        v = dict(self.nominal)
        v.update(values)
        p = kernel_vector(v)
        offset = v["theta_offset"]
        sim = np.full((stop, 2), np.nan)
        for k, (i0, i1) in enumerate(self.segments):
            if i0 >= stop:
                break
            i1 = min(i1, stop)
            state = np.zeros(2) if self.rests else np.array([self.states0[k, 0] - offset, self.states0[k, 1]])
            out = np.empty((i1 - i0 + 1, 2))
            rows = self.motion[(i0 - 1) * self.per_sample : (i1 - 1) * self.per_sample + 1]
            platform_trace(
                state, p, v["M2"], v["C2"], v["gain_Fs"], rows, self.per_sample, self.dt, self.substeps, out,
                self.point, self.kinked,
            )  # fmt: skip
            sim[i0:i1] = out[1:]
        return {"theta": sim[:, 0] + offset, "Fs": sim[:, 1]}


class NumericalReplay(Replay):
    """The numerical model of a substructured record, driven by the forces the controller was given.

    Parameters
    ----------
    record : Record
        A ``substructured`` record with ``Fe`` and ``Fs`` (or ``F_fb``).
    horizon : float, optional
        Segment length [s] (default 4).
    folds : int
        Cross-validation folds.
    """

    def __init__(self, record: Record, horizon: float | None = None, folds: int = FOLDS):
        self.kind = "numerical"
        channel = "y_star" if "y_star" in record.data else "y_cmd"
        self._compare(record, (channel,), folds, max(1, int(math.ceil(SETTLE / record.dt))))
        self.output = channel
        # The controller's own numbers: no sensor noise, but the replay's conventions (integrator,
        # force hold, predictor) may differ from the controller's by this much.
        self.noise[channel] = CONVENTION_FLOOR * self.scale[channel]
        self.nominal = nominal_values(record.params, record.tau)
        self.fits_initial_state = False
        if channel == "y_cmd":
            self.nuisance = ("command_lead",)
            self.nuisance_scale = {"command_lead": 0.005}
            self.nuisance_bounds = {"command_lead": (-MAX_LEAD, MAX_LEAD)}
        self.initial_guess = {"command_lead": 0.0}
        self.substeps = 1
        self.force = record.channel("Fe")
        self.force_half = midpoint_values(self.force)
        self.feedback = record.channel("F_fb" if "F_fb" in record.data else "Fs")
        out = self.meas[channel]
        self.slope = smoothed(out, self.dt)[1]
        self.horizon = DEFAULT_HORIZON if horizon is None else float(horizon)
        self.segments = _cut(self.start, self.n, max(20, int(round(self.horizon / self.dt))))
        # The controller's integrator, read off its own exact output: the model integrated each way,
        # the closer one kept (RK4 and central difference differ by far more than the floor: the
        # external force sampled at the tick, half a tick late, is a damping error). The models are
        # the nominal and, each refined by a few Gauss-Newton steps, the oscillator's K, M or C where
        # the record points (identify/oscillator.py): with a coded mass 6 % off the nominal, the nominal alone
        # read a central difference off an RK4 controller (0.413 against 0.420), and no mass then
        # fitted the output to its floor.
        ident = self.identification()
        errors = {}
        for name in INTEGRATORS:
            self.integrator = name
            errors[name] = self.nrmse(self.simulate({}))
            if ident is not None:
                errors[name] = min(errors[name], *(self._refined_error(p, ident.alone[p]) for p in ("K", "M", "C")))
        self.integrator = min(INTEGRATORS, key=lambda name: errors[name])
        self.integrator_errors = errors

    def _refined_error(self, param: str, start: float, steps: int = 3) -> float:
        """The least NRMSE over a few Gauss-Newton steps in ``param`` alone from ``start`` (the others nominal)."""
        value = float(start)
        best = math.inf
        for _ in range(steps):
            r = self.residuals(self.simulate({param: value}), self.eval_idx)
            if not np.all(np.isfinite(r)):
                break
            best = min(best, float(np.sqrt(np.mean(r * r))))
            h = 1e-6 * max(abs(value), 1.0)
            j = (self.residuals(self.simulate({param: value + h}), self.eval_idx) - r) / h
            if not (np.all(np.isfinite(j)) and j @ j > 0):
                break
            value -= float(j @ r) / float(j @ j)
        r = self.residuals(self.simulate({param: value}), self.eval_idx)
        return min(best, float(np.sqrt(np.mean(r * r)))) if np.all(np.isfinite(r)) else best

    def _shifted(self, y: np.ndarray, yd: np.ndarray, at: np.ndarray) -> np.ndarray:
        """Cubic Hermite values of the sampled (y, y') at fractional sample positions ``at``."""
        j = np.clip(np.floor(at).astype(np.int64), 0, len(y) - 2)
        s = np.clip(at - j, 0.0, 1.0)
        s2, s3 = s * s, s * s * s
        h = self.dt
        return (
            (2 * s3 - 3 * s2 + 1) * y[j]
            + (s3 - 2 * s2 + s) * h * yd[j]
            + (-2 * s3 + 3 * s2) * y[j + 1]
            + (s3 - s2) * h * yd[j + 1]
        )

    def simulate(self, values: dict[str, float], stop: int | None = None) -> dict[str, np.ndarray]:
        stop = self.n if stop is None else stop
        v = dict(self.nominal, **self.initial_guess)
        v.update(values)
        model = (v["M"] - self.nominal["M2"], v["C"] - self.nominal["C2"], v["K"], v["k3"])
        lead = v["command_lead"] if self.output == "y_cmd" else 0.0
        shift = lead / self.dt
        extra = int(math.ceil(max(shift, 0.0))) + 1
        sim = np.full(stop, np.nan)
        if model[0] <= 0.0:
            return {self.output: sim}
        out_meas, slope = self.meas[self.output], self.slope
        for i0, i1 in self.segments:
            if i0 >= stop:
                break
            i1 = min(i1, stop)
            end = min(i1 + extra, self.n)
            # y*(t0) is the output a lead earlier (the predictor's input).
            y0 = self._shifted(out_meas, slope, np.array([i0 - shift]))[0]
            yd0 = self._shifted(slope, np.gradient(slope, self.dt), np.array([i0 - shift]))[0]
            out = np.empty((end - i0, 2))
            numerical_trace(
                np.array([y0, yd0]), model, self.force[i0:end], self.force_half[i0 : end - 1], self.feedback[i0:end],
                v["gain"], self.dt, out, self.integrator == "central",
            )  # fmt: skip
            at = np.arange(i1 - i0) + shift
            sim[i0:i1] = self._shifted(out[:, 0], out[:, 1], at) if shift else out[: i1 - i0, 0]
        return {self.output: sim}


def physical_substeps(dt: float) -> int:
    """Pendulum RK4 steps per sample: steps of at most :data:`~.replay.MAX_STEP`."""
    return max(1, math.ceil(dt / MAX_STEP - 1e-9))
