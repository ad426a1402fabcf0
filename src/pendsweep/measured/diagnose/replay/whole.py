"""Replay a record: simulate its model driven by its recorded inputs.

``free_decay``
    Fixed pivot, single shooting over the whole record. The initial angle and
    velocity (release velocity unknown) are nuisance parameters fitted with
    every model.
``forced``
    Eqs. (1)-(2) driven by the recorded ``Fe``. Long horizons are meaningless
    for chaotic motion, so the record is cut into short segments (``horizon``
    seconds, 4 s by default) and each is simulated from the measured state at
    its start (Savitzky-Golay estimates of y, ydot, theta, thetadot): a
    short-horizon prediction error (multiple shooting with states taken from
    the data).
``substructured``
    The substructuring loop (Eq. (3) numerical model, load-cell feedback of
    Eq. (4), actuator ``x(t) = y_cmd(t - tau)``) driven by the recorded
    ``Fe``, in short-horizon segments started from the recorded ``y_cmd``
    (as ``y*``, exact: it is the controller's own number) and the estimated
    pendulum state, with the recorded command history feeding the delayed
    actuator and the recorded load-cell reading fed back over a segment's
    first tick. The first :data:`COMMAND_HISTORY` seconds of the record only
    serve as command history (the actuator there follows commands sent before
    the record began) and are not compared. Compared channels: y (= x),
    theta, y_cmd and Fs when recorded. The numerical mass and damping ``M1 = M - M2``,
    ``C1 = C - C2`` are code, so ``platform_mass``/``platform_damping``
    change the physical M2/C2 only and ``oscillator_mass``/``_damping`` the
    numerical M1/C1.

Compared samples: the part of the record where the data move (a channel's
peak-to-peak over :data:`MOTION_WINDOW` exceeds a few quantisation steps and
noise levels, dilated by the window): a pendulum resting at the end of a free
decay, carries no information and is left out. A channel constant over the
whole record (a pendulum resting through a forced test) is compared by its
level: its residual is relative to the level and its noise is zero.
The compared samples are cut into ``folds x BLOCKS_PER_FOLD`` contiguous
blocks; fold ``k`` holds out blocks ``k, k + folds, ...`` (blocked
cross-validation, see :mod:`pendsweep.measured.diagnose.fit`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from ....errors import ConfigError
from ....kernels import driven_trace, pendulum_trace, substructured_replay
from ....model.params import ENCODER_RESOLUTION, kernel_vector
from ...records import Record
from ..effects import nominal_values
from ..identify.oscillator import identify_oscillator
from ..signals import MAX_STROKE, midpoint_values, noise_std, rounding_std, smoothed, smoothing_gain

#: One-sigma uncertainty [rad] of an encoder zero read off a resting pendulum's constant angle:
#: uniform within half an encoder step (Table III's; one level shows no step of its own).
REST_LEVEL_SIGMA = ENCODER_RESOLUTION / math.sqrt(12.0)

#: Channels compared per kind.
CHANNELS = {"free_decay": ("theta",), "forced": ("y", "theta"), "substructured": ("y", "theta", "y_cmd", "Fs")}
#: Default short-horizon segment length for forced records [s].
DEFAULT_HORIZON = 4.0
#: Cross-validation folds and contiguous blocks per fold.
FOLDS = 5
BLOCKS_PER_FOLD = 4
#: Window of the motion test [s].
MOTION_WINDOW = 0.25
#: Largest integration step of free-swing replays [s] (the paper's 1 ms).
MAX_STEP = 1e-3
#: Leading part of a substructured record that only serves as command history [s]: the
#: actuator's position there follows commands sent before the record began.
COMMAND_HISTORY = 0.05
NUISANCE = ("theta_init", "thetadot_init")
#: Gauss-Newton passes fitting each segment's initial state of a forced record (see
#: Replay._fit_segment_states).
STATE_PASSES = 1
#: Each segment's state and LVDT offset are fitted on its first this many seconds [s]: about one period
#: of the oscillator and half of the pendulum's, so that they are the segment's start as the data near
#: it say (as the smoothed estimate was, more precisely) and absorb no model error later in the segment;
#: fitted on whole segments, a fold that holds out a segment's first block would extrapolate the free
#: response backwards from samples seconds later.
STATE_WINDOW = 0.5
#: A forced record's channel whose spread is below this multiple of its noise is weighed in the fits by
#: its noise instead (Replay.fit_weight).
FIT_SNR = 100.0
#: Finite-difference steps of a segment's state: y [m], y' [m/s], theta [rad], theta' [rad/s]
#: (the replay is linear in such small changes; far above float64's resolution of the channels).
STATE_STEPS = np.array([1e-7, 1e-6, 1e-7, 1e-6])


def check_displacement_units(record: Record) -> None:
    """Refuse a displacement column the record's kind compares that reaches beyond any stroke of the rig
    (:data:`MAX_STROKE`): millimetres read as metres, which a replay would otherwise fit as an effect."""
    for col in ("y", "y_cmd"):
        if col not in CHANNELS.get(record.kind, ()) or col not in record.data:
            continue
        reach = float(np.max(np.abs(record.channel(col))))
        if reach > MAX_STROKE:
            raise ConfigError(
                f"{record.name}: column {col!r} reaches {reach:.3g} m, beyond any actuator stroke of this rig "
                f"({MAX_STROKE:g} m): millimetres read as metres? Declare its unit in the metadata's columns, "
                f'e.g. {{"{col}": {{"unit": "mm"}}}}'
            )


class Replay:
    """A record ready for simulation and comparison.

    Parameters
    ----------
    record : Record
    horizon : float, optional
        Segment length [s] for forced records (default :data:`DEFAULT_HORIZON`).
    folds : int
        Cross-validation folds (2 to 20).
    """

    #: Nuisance parameters fitted with every model of this kind (free decays: the release state).
    nuisance: tuple[str, ...] = ()
    #: Weight of each channel's normalised residual in the least squares (default 1: see :meth:`fit_residuals`).
    fit_weight: dict[str, float] = {}
    #: Their scales for the fit [their units], and bounds (default: none).
    nuisance_scale: dict[str, float] = {}
    nuisance_bounds: dict[str, tuple[float, float]] = {}

    def __init__(self, record: Record, horizon: float | None = None, folds: int = FOLDS):
        if record.kind not in CHANNELS:
            raise ConfigError(f"kind {record.kind!r} cannot be replayed yet; supported kinds: {', '.join(CHANNELS)}")
        self.kind = record.kind
        check_displacement_units(record)
        # Substructured: the first samples replay commands from before the record (unknown).
        start = int(math.ceil(COMMAND_HISTORY / record.dt)) if self.kind == "substructured" else 0
        self._compare(record, CHANNELS[record.kind], folds, start)
        if self.kind == "free_decay":
            self.nuisance, self.nuisance_scale = NUISANCE, {"theta_init": 0.01, "thetadot_init": 0.05}
        self.nominal = nominal_values(record.params, record.tau)
        est = {c: smoothed(record.channel(c), self.dt) for c in ("y", "theta", "y_cmd") if c in record.data}
        if self.kind == "free_decay":
            self.horizon = self.t[-1]
            self.segments = [(0, self.n)]
            self.initial_guess = {"theta_init": est["theta"][0][0], "thetadot_init": est["theta"][1][0]}
        else:
            self.horizon = DEFAULT_HORIZON if horizon is None else float(horizon)
            if not (math.isfinite(self.horizon) and self.horizon > 20 * self.dt):
                raise ConfigError(f"horizon = {horizon!r} s must exceed 20 samples ({20 * self.dt:g} s)")
            h = int(round(self.horizon / self.dt))
            self.segments = _cut(self.start, self.n, h)
            starts = np.array([s for s, _ in self.segments])
            # y* of a substructured test is the command (no prediction).
            y = est["y_cmd" if self.kind == "substructured" else "y"]
            self.states0 = np.stack(
                [y[0][starts], y[1][starts], est["theta"][0][starts], est["theta"][1][starts]], axis=1
            )
            if self.kind == "substructured":
                self.command = np.ascontiguousarray(record.channel("y_cmd"))
                self.command_slope = np.ascontiguousarray(est["y_cmd"][1])
                # The command is the controller's own exact number: a segment's y* starts from it, not
                # from its smoothed estimate, or the delayed command jumps where the measured history
                # hands over to the replayed commands (a force spike of ms * jump / dt^2 there).
                self.states0[:, 0] = self.command[starts]
                # The load-cell reading at a segment's start is fed back over its first tick.
                self.force_start = record.channel("Fs")[starts] if "Fs" in record.data else np.full(len(starts), np.nan)
                # The load cell averaged over the tick (the loop's own) or sampled at it (daq.load_cell).
                self.point = record.sampling("load_cell") == "point"
            self.force = record.channel("Fe")
            self.force_half = midpoint_values(self.force)
            self.initial_guess = {}
            if self.kind == "forced" and "y" in self.noise and "y" not in self.constant:
                # The replay is driven by the recorded force, whose sensor noise moves the replayed y:
                # white noise of variance s^2 per sample through the oscillator gives y a variance of
                # s^2 dt / (2 K C) (the integral of |H|^2 over frequency).
                force_var = noise_std(self.force) ** 2 * self.dt / (2.0 * self.nominal["K"] * self.nominal["C"])
                self.noise["y"] = math.sqrt(self.noise["y"] ** 2 + force_var)
            if self.kind == "forced":
                # A channel that barely moves is weighed by its noise, not its spread: a small pendulum's
                # angle, read in a few encoder steps, has a spread only 10 to 30 times its noise (the LVDT's
                # is 350 times), and weighted by its spread it bent the oscillator's fit to that noise (a
                # stiffness 0.6 % off, y left at 100 x its noise variance). Channels moving more than
                # FIT_SNR times their noise keep the pooled error's weight: there the angle's model-form
                # error, not its noise, dominates, and weighted by its noise it bent the oscillator instead.
                self.fit_weight = {
                    c: min(1.0, self.scale[c] / (FIT_SNR * self.noise[c])) if self.noise[c] > 0 else 1.0
                    for c in self.channels
                }
            # Each channel's weight in the fit of the segments' states and offsets (its noise), and the
            # smoothed starting states' own uncertainty, their prior in that fit.
            self._state_sigma = {c: self.noise[c] or self.scale[c] for c in self.channels}
            gain = smoothing_gain(self.n, self.dt, starts)
            self._prior_sigma = np.concatenate([gain * self._state_sigma.get(c, 0.0) for c in ("y", "theta")], axis=1)
        self.fits_initial_state = self.kind == "free_decay"
        # Free swings integrate with steps of at most MAX_STEP: the held sgn of the
        # Coulomb term makes the model depend on the step.
        self.substeps = max(1, math.ceil(self.dt / MAX_STEP - 1e-9))

    def identification(self):
        """The oscillator's dynamics read off this record (:mod:`..identify.oscillator`; None for
        kinds without an oscillator), computed once."""
        if not hasattr(self, "_identification"):
            self._identification = identify_oscillator(self)
        return self._identification

    def _compare(self, record: Record, channels: tuple[str, ...], folds: int, start: int) -> None:
        """Set up what is compared: ``channels`` (those recorded), their noise, the moving samples, the folds.

        Samples before ``start`` are never compared.
        """
        if not 2 <= folds <= 20:
            raise ConfigError(f"folds = {folds!r} must lie in [2, 20]")
        self.record = record
        self.dt = record.dt
        self.n = len(record.data)
        self.t = record.t - record.t[0]
        every = tuple(c for c in channels if c in record.data)
        # A channel that never changes (a pendulum resting through a forced record) still says where
        # it rests: it is compared by its level. Its error is relative to that level (a zero level
        # takes unit scale) and its noise is zero (an exactly constant quantised reading), so a model
        # that holds the level adds nothing to the error or to the noise floor, and one that cannot
        # hold it (an encoder zero error) shows a discrepancy.
        self.constant = tuple(c for c in every if np.ptp(record.channel(c)) == 0.0)
        if len(self.constant) == len(every):
            raise ConfigError(
                f"{record.name}: every compared channel ({', '.join(every)}) is constant; nothing to compare"
            )
        self.channels = every
        self.meas = {c: record.channel(c) for c in self.channels}
        self.scale = {
            c: (abs(float(self.meas[c][0])) or 1.0) if c in self.constant else float(np.std(self.meas[c]))
            for c in self.channels
        }
        window = max(5, int(round(MOTION_WINDOW / self.dt)))
        self.noise = {
            c: 0.0 if c in self.constant else max(noise_std(self.meas[c]), rounding_std(self.meas[c], window))
            for c in self.channels
        }
        # The pendulum rests through the record: its replay starts at its equilibrium (simulate)
        # and its constant angle locates the encoder zero to REST_LEVEL_SIGMA.
        self.rests = "theta" in self.constant
        self.folds = int(folds)
        self.start = start
        self.moving = self._moving()
        self.moving[: self.start] = False
        self.eval_idx = np.flatnonzero(self.moving)
        n_blocks = self.folds * BLOCKS_PER_FOLD
        if len(self.eval_idx) < 10 * n_blocks:
            raise ConfigError(
                f"{record.name}: the data move in {len(self.eval_idx)} samples, too few for "
                f"{n_blocks} cross-validation blocks of 10 samples"
            )
        self.blocks = np.array_split(self.eval_idx, n_blocks)

    # -- simulation -------------------------------------------------------------
    def simulate(self, values: dict[str, float], stop: int | None = None) -> dict[str, np.ndarray]:
        """Simulated measured channels for the samples ``[0, stop)``.

        ``values`` maps vocabulary parameters (missing ones take the nominal)
        and, for free decays, ``theta_init``/``thetadot_init``. On forced
        records each segment's initial state and LVDT offset are nuisances
        fitted with the model (:meth:`_fit_segment_states`). Non-finite output
        marks a diverged simulation.
        """
        stop = self.n if stop is None else stop
        v = dict(self.nominal, **self.initial_guess)
        v.update(values)
        p = kernel_vector(v)
        theta_offset = v["theta_offset"]
        if self.kind == "free_decay":
            out = np.empty((stop, 2))
            state = np.array([v["theta_init"] - theta_offset, v["thetadot_init"]])
            pendulum_trace(state, p, self.dt, self.substeps, out)
            return {"theta": out[:, 0] + theta_offset}
        if self.kind == "substructured":
            return self._loop(v, p, theta_offset, stop)
        starts = np.array([self._segment_start(k, theta_offset) for k in range(len(self.segments))])

        def driven(states: np.ndarray, span: int | None = None) -> dict[str, np.ndarray]:
            """The segments replayed from ``states``, each over its first ``span`` samples only when given."""
            sim = np.empty((stop, 4))
            for k, (i0, i1) in enumerate(self.segments):
                if i0 >= stop:
                    break
                i1 = min(i1, stop, i0 + span) if span else min(i1, stop)
                driven_trace(
                    states[k], p, self.force[i0:i1], self.force_half[i0 : i1 - 1], v["gain"], self.dt, sim[i0:i1]
                )
            return {"y": sim[:, 0], "theta": sim[:, 2] + theta_offset}

        return self._fit_segment_states(driven, starts, stop)

    def _segment_start(self, k: int, theta_offset: float) -> np.ndarray:
        """Initial state of segment ``k`` (y, y', theta, theta') for the trial encoder zero ``theta_offset``.

        A pendulum that rests through the record hangs at its equilibrium: every
        segment starts it exactly there, whatever zero is tried, so that the
        model's angle stays exactly at rest (started a micro-radian off, it moves,
        and freeing any damping parameter then "explains" that motion on a
        noiseless constant channel).
        """
        state = self.states0[k].copy()
        state[2:] = 0.0 if self.rests else (state[2] - theta_offset, state[3])
        return state

    def _fit_segment_states(self, replay, states: np.ndarray, stop: int) -> dict[str, np.ndarray]:
        """``replay(states)`` with each segment's initial state and LVDT offset fitted to its first samples.

        The smoothed estimate of a segment's starting state carries the
        sensors' error: a Savitzky-Golay slope of a quantised angle is off by
        about ``q / window`` (0.02 rad/s for Table III's encoder at 500 Hz), and
        at a record's first sample the one-sided window is worse. A lightly
        damped pendulum carries that error through its segment, so even the
        true model missed a small swing by tens of times the encoder's noise.
        The LVDT's offset and slow drift, and the quasi-static response to the
        load cell's drift in the recorded ``Fe``, shift y by a few tens of
        micrometres. Both are nuisances of every model (variable projection),
        fitted on the compared samples of each segment's first
        :data:`STATE_WINDOW` seconds: :data:`STATE_PASSES` Gauss-Newton passes,
        the residuals weighted by each channel's noise (a likelihood: weighted
        by the channels' spreads, a pendulum that barely moves would bend the
        oscillator's start to fit its angle), the smoothed start a prior
        weighted by its own uncertainty (a state the window does not determine,
        the slope of a pendulum that barely moves, stays near it). The Jacobian
        takes one perturbed replay per state component (the segments are
        independent, so one replay moves them all); the offset enters linearly.
        A segment keeps its pass only where that lowers its objective (a
        chaotic segment's linearisation can fail). A pendulum that rests
        through the record keeps its exact equilibrium (:meth:`_segment_start`).
        """
        sim = replay(states)
        prior_mean = states.copy()
        window = int(round(STATE_WINDOW / self.dt))
        near_start = np.zeros(self.n, dtype=bool)
        for i0, i1 in self.segments:
            near_start[i0 : min(i0 + window, i1, stop)] = True
        rows = np.flatnonzero(self.moving & near_start)
        channels = [c for c in self.channels if c not in self.constant]
        free = [0, 1] if self.rests else [0, 1, 2, 3]
        fits_offset = "y" in channels
        n_seg = len(self.segments)
        # Row ranges of each segment in ``rows`` (sorted sample indices).
        bounds = np.searchsorted(rows, [i0 for i0, _ in self.segments] + [stop])
        lengths = np.diff(bounds)
        sigma = np.array([self._state_sigma[c] for c in channels])[:, None]
        meas = np.stack([self.meas[c][rows] for c in channels])
        offsets = np.zeros(n_seg)

        def weighted(sim_: dict[str, np.ndarray], offsets_: np.ndarray) -> np.ndarray:
            """Residuals in units of each channel's noise: (channels, rows)."""
            out = np.stack([sim_[c][rows] for c in channels]) - meas
            if fits_offset:
                out[channels.index("y")] += np.repeat(offsets_, lengths)
            return out / sigma

        prior_weight = np.zeros_like(states)
        prior_weight[:, free] = 1.0 / np.maximum(self._prior_sigma[:, free], 1e-300) ** 2

        def objective(r: np.ndarray, states_: np.ndarray) -> np.ndarray:
            """Each segment's squared residuals plus its states' prior term (inf where not finite)."""
            per_row = np.sum(r * r, axis=0)
            sums = np.add.reduceat(per_row, bounds[:-1]) if len(per_row) else np.zeros(n_seg)
            sums = np.where(lengths > 0, sums, 0.0) + np.sum(prior_weight * (states_ - prior_mean) ** 2, axis=1)
            return np.where(np.isfinite(sums), sums, np.inf)

        for _ in range(STATE_PASSES):
            r = weighted(sim, offsets)
            if not np.all(np.isfinite(r)):
                break
            columns = []
            for j in free:
                moved = states.copy()
                moved[:, j] += STATE_STEPS[j]
                columns.append((weighted(replay(moved, window), offsets) - r) / STATE_STEPS[j])
            if fits_offset:
                unit = np.zeros_like(r)
                unit[channels.index("y")] = 1.0 / sigma[channels.index("y"), 0]
                columns.append(unit)
            jac = np.stack(columns, axis=-1)  # (channels, rows, parameters)
            state_step, offset_step = np.zeros_like(states), np.zeros(n_seg)
            for k in np.flatnonzero(lengths):
                jk, rk = jac[:, bounds[k] : bounds[k + 1]], r[:, bounds[k] : bounds[k + 1]]
                if not np.all(np.isfinite(jk)):
                    continue
                # The smoothed start is the prior (maximum a posteriori): the data move a state only as far
                # as they determine it.
                prior = np.zeros(jk.shape[-1])
                prior[: len(free)] = prior_weight[k, free]
                normal = np.einsum("crp,crq->pq", jk, jk) + np.diag(prior)
                gradient = np.einsum("crp,cr->p", jk, rk)
                gradient[: len(free)] += prior[: len(free)] * (states[k, free] - prior_mean[k, free])
                step = np.linalg.lstsq(normal, -gradient, rcond=1e-12)[0]
                state_step[k, free] = step[: len(free)]
                offset_step[k] = step[-1] if fits_offset else 0.0
            trial = replay(states + state_step)
            after = objective(weighted(trial, offsets + offset_step), states + state_step)
            keep = (after < objective(r, states)) & (lengths > 0)
            if not keep.any():
                break
            states = np.where(keep[:, None], states + state_step, states)
            offsets = np.where(keep, offsets + offset_step, offsets)
            sim = trial if keep.all() else replay(states)
        if fits_offset and offsets.any():
            sim = dict(sim, y=sim["y"] + np.repeat(offsets, [i1 - i0 for i0, i1 in self.segments])[: len(sim["y"])])
        return sim

    def _loop(self, v: dict[str, float], p: np.ndarray, theta_offset: float, stop: int) -> dict[str, np.ndarray]:
        sim = np.empty((stop, 4))
        sim[: self.start] = np.nan  # command history, not replayed
        nom = self.nominal
        # M1, C1 are the numerical model's code values: M and C move them, M2 and C2 do not.
        M1 = v["M"] - nom["M2"]
        C1 = v["C"] - nom["C2"]
        if M1 <= 0:
            sim.fill(np.nan)
        for k, (i0, i1) in enumerate(self.segments):
            if i0 >= stop or M1 <= 0:
                break
            state = self._segment_start(k, theta_offset)
            cmd, cmdd = self.command.copy(), self.command_slope.copy()
            substructured_replay(
                state,
                p,
                M1,
                C1,
                v["M2"],
                v["C2"],
                self.force,
                self.force_half,
                v["gain"],
                v["gain_Fs"],
                v["tau"],
                self.dt,
                1,
                cmd,
                cmdd,
                i0,
                sim[i0 : min(i1, stop)],
                self.force_start[k],
                self.point,
            )
        return {"y": sim[:, 0], "theta": sim[:, 1] + theta_offset, "Fs": sim[:, 2], "y_cmd": sim[:, 3]}

    def _moving(self) -> np.ndarray:
        """Samples where some compared channel moves, by a peak-to-peak test over a sliding window."""
        w = max(5, int(round(MOTION_WINDOW / self.dt)))
        mask = np.zeros(self.n, dtype=bool)
        for c in self.channels:
            if c in self.constant:
                continue
            x = self.meas[c]
            steps = np.abs(np.diff(x))
            quantum = float(steps[steps > 0].min()) if np.any(steps > 0) else 0.0
            threshold = max(3.0 * quantum, 6.0 * self.noise[c])
            ptp = maximum_filter1d(x, w) - minimum_filter1d(x, w)
            mask |= ptp > threshold
        # Dilate: the window around a moving sample still belongs to the motion.
        return maximum_filter1d(mask.astype(np.uint8), 2 * w + 1).astype(bool)

    def fold_indices(self, k: int) -> np.ndarray:
        """Sample indices held out by fold ``k``."""
        return np.concatenate(self.blocks[k :: self.folds])

    def train_indices(self, k: int) -> np.ndarray:
        """Compared sample indices fitted in fold ``k``."""
        return np.concatenate([b for j, b in enumerate(self.blocks) if j % self.folds != k])

    # -- errors -----------------------------------------------------------------
    def residuals(self, sim: dict[str, np.ndarray], idx: np.ndarray | slice) -> np.ndarray:
        """Normalised residuals (sim - measured) / std(measured) at ``idx``, channels stacked."""
        r = [(sim[c][idx] - self.meas[c][idx]) / self.scale[c] for c in self.channels]
        return np.concatenate(r)

    def fit_residuals(self, sim: dict[str, np.ndarray], idx: np.ndarray | slice) -> np.ndarray:
        """The residuals the least squares minimise: :meth:`residuals`, each channel weighted by
        :attr:`fit_weight` (1 but for a forced record's channel that barely moves)."""
        r = [self.fit_weight.get(c, 1.0) * (sim[c][idx] - self.meas[c][idx]) / self.scale[c] for c in self.channels]
        return np.concatenate(r)

    def nrmse(self, sim: dict[str, np.ndarray], idx: np.ndarray | slice | None = None) -> float:
        """RMS over channels of RMSE / std(measured channel) at ``idx`` (default: the compared samples)."""
        r = self.residuals(sim, self.eval_idx if idx is None else idx)
        return float(np.sqrt(np.mean(r * r))) if np.all(np.isfinite(r)) else math.inf

    def noise_floor(self) -> float:
        """NRMSE that sensor noise alone gives, estimated from the data."""
        return float(np.sqrt(np.mean([(self.noise[c] / self.scale[c]) ** 2 for c in self.channels])))


def _cut(start: int, stop: int, h: int) -> list[tuple[int, int]]:
    """Segments of about ``h`` samples covering ``[start, stop)``; a short tail joins the last."""
    edges = list(range(start, stop, h)) + [stop]
    if len(edges) > 2 and edges[-1] - edges[-2] < h // 2:
        del edges[-2]
    return list(zip(edges[:-1], edges[1:]))
