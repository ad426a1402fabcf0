"""Fits of candidate effects, their cross-validated comparison and the verdict.

One record or several records of one rig form a :class:`Problem`. Physical
parameters (ModelParams fields) are shared by all records; measurement-chain
parameters (``gain``, ``theta_offset``, ``tau``, ``gain_Fs``) and, on free
decays, the initial angle and velocity belong to each record (on several free
decays also each record's encoder zero, fitted after the rest). Every model (the
nominal included) is fitted with :func:`scipy.optimize.least_squares` on the
compared samples (where the data move, see :class:`~.replay.Replay`).
Several records are fitted in a canonical order (by content), shared
parameters start from the median of the records' data-based starts, and ties
are broken by name, so the verdict does not depend on the order of the files.

Validation
----------
*One record*: blocked cross-validation. The compared samples are cut into
``folds x BLOCKS_PER_FOLD`` contiguous blocks; fold ``k`` refits the model
without blocks ``k, k + folds, ...`` and predicts them. *Several records*:
leave-one-record-out; the shared physics is fitted on the other records, the
left-out record's own parameters (initial state, chain) on itself with the
physics fixed, and its prediction error is the cross-record error. Either way
every compared sample gets an out-of-fold prediction, and the cross-validated
error ``error_cv`` is the NRMSE of those predictions. On one record a fold's refit is one Gauss-Newton step from the fit on all
compared samples, using that fit's Jacobian rows of the fold's training
samples (exact for a residual linear in the parameters; a full refit per fold
would multiply the cost by the number of folds). The fold estimates give a
jackknife uncertainty, which accounts for correlated residuals and model-form
error that the Jacobian does not see.

Verdict
-------
The candidate with the lowest ``error_cv`` is named when all hold against the
nominal model (``b``: base, ``m``: model, ``f``: noise floor):

1. it explains a share of the base's excess squared error,
   ``(E_b^2 - E_m^2) / (E_b^2 - f^2) >= SHARE_MIN``, and more than
   ``FLOOR_SHARE f^2``;
2. it improves the out-of-fold predictions consistently: one-sided Wilcoxon
   signed-rank test on the blocks' differences of mean squared error
   (zero differences split, so constant or quantised blocks carry their weight
   instead of breaking the test), ``p < P_VALUE``;
3. its parameter stands out of its jackknife uncertainty, ``z >= Z_MIN``, with
   the same sign of the change in every fold (an encoder zero read off a resting
   pendulum, whose error is bounded by half an encoder step, ``z >= Z_BOUNDED``:
   outside that half step).

A candidate whose estimate lies more than ``IMPLAUSIBLE_FACTOR`` times from its
nonzero nominal is not named (it absorbs something else); candidates that the
verdict does not beat on the held-out blocks are reported in ``tied_with``.

A second cause joins the best single one only when the pair passes the same
three tests against the single cause (``SECOND_SHARE_MIN`` of the single's
excess), each of the two parameters separately, and, on substructured records,
beats the single cause with the actuator delay freed (so it is not absorbing
the actuator's model-form error). Otherwise one cause is named and what
remains is reported: ``unexplained`` is true when the verdict model's
cross-validated squared error exceeds ``UNEXPLAINED_RATIO[kind] x f^2``, or,
on kinds listed in :data:`CHANNEL_RATIO`, when one sensor channel's
cross-validated mean square exceeds ``CHANNEL_RATIO[kind]`` times its own noise
variance. The pooled floor of a substructured record is the load cell's noise
(its noise-to-signal ratio is about 30 times the LVDT's and 100 times the
encoder's), so a structured residual in x or theta hides below a pooled
threshold; the channel test sees it. The same two tests decide whether a second
round is run (with ``SECOND_ROUND_RATIO`` pooled).
The thresholds were chosen on the calibration seed range of
:mod:`pendsweep.diagnose.testbench` only (``docs/measured-data.md``).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from joblib import Parallel, delayed
from scipy import stats
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from ..errors import ConfigError
from .effects import CHAIN_PARAMS, EFFECTS, applicable, effect
from .replay import NUISANCE, REST_LEVEL_SIGMA, Replay

FLOOR_SHARE = 0.25
SHARE_MIN = 0.5
SECOND_SHARE_MIN = 0.5
P_VALUE = 1e-3
Z_MIN = 4.0
#: A resting pendulum's encoder zero is known to within half an encoder step, uniformly (one-sigma
#: step / sqrt(12)): a change beyond that half step, z >= sqrt(3), is certain, where Z_MIN, made
#: for Gaussian errors, would discard a one-step reading.
Z_BOUNDED = math.sqrt(3.0)
#: The second round runs when the best single cause leaves more than this multiple of the floor^2.
SECOND_ROUND_RATIO = 2.0
#: The second cause is sought among this many next-best single causes.
PARTNERS = 3
#: Second rounds start from this many best single causes.
BEAM = 2
#: Cross-validated squared error above this multiple of the floor^2 is "unexplained" (per kind).
UNEXPLAINED_RATIO = {"free_decay": 3.0, "forced": 30.0, "substructured": 4.5}
#: One sensor channel's cross-validated mean square above this multiple of its own noise variance
#: is a structured residual too (kinds whose pooled floor one noisy channel dominates).
CHANNEL_RATIO = {"substructured": 60.0}
#: An estimate more than this factor from its nonzero nominal is physically implausible: the cause
#: is not named (its parameter is absorbing something else). The identifiable ranges are 1.03-8 x
#: nominal; on the calibration range A the largest ratio of any best or runner-up single cause was
#: 8.2 (of any pair's 32), on the three real records 76 (b3); a resting pendulum's encoder zero,
#: before its constant angle was compared, was absorbed by b3 at 2.8e5 x nominal.
IMPLAUSIBLE_FACTOR = 1000.0
#: Factor from a fit's own one-sigma uncertainty (Jacobian, raised to the fold jackknife; what the
#: tests use) to the stated one, by record kind. On the calibration range A (49 right single
#: verdicts) the median |estimate - truth| / sigma was 1.23 (free decay), 2.32 (forced) and 0.44
#: (substructured); each factor brings it to 0.674, the median |z| of a normal error, and none is
#: below 1 (the substructured jackknife is already wide). Held-out check: the diagnosis
#: benchmark's ``uncertainty_coverage`` on range B.
UNCERTAINTY_CALIBRATION = {"free_decay": 1.83, "forced": 3.44, "substructured": 1.0}
#: Channels recorded exactly (the controller's own command): no sensor noise to compare with.
EXACT_CHANNELS = ("y_cmd",)
#: Scales of the free-decay nuisance parameters [rad], [rad/s].
_NUISANCE_SCALE = {"theta_init": 0.01, "thetadot_init": 0.05, "theta_offset": 0.01}
_DIVERGED = 1e3


@dataclass(frozen=True)
class _Param:
    key: str  # name in Fit.values: the parameter, with "@i" for a per-record one of several records
    record: int | None  # None: shared by all records
    start: float
    scale: float
    lower: float
    upper: float


def record_key(replay: Replay) -> tuple[str, str]:
    """Canonical sort key of a record: a digest of its compared channels, then its name.

    The content decides (a renamed file keeps its place); the name breaks the tie
    of two identical records. Least squares on the records in this order is the
    same computation, bit for bit, whatever order the user listed them in.
    """
    digest = hashlib.sha256(replay.kind.encode())
    for c in replay.channels:
        digest.update(c.encode())
        digest.update(np.ascontiguousarray(replay.meas[c], dtype=np.float64).tobytes())
    return digest.hexdigest(), replay.record.name


class Problem:
    """One record, or several records of one rig, to be fitted together.

    Parameters
    ----------
    replays : list of Replay
        Records of one kind. Physical parameters are shared; chain parameters
        and free-decay initial states are per record. They are kept in a
        canonical order (by content, see :func:`record_key`), so that the fit,
        the folds and the verdict do not depend on the order they were given in;
        ``param@i`` keys refer to that order (``validation.records``).
    """

    def __init__(self, replays: list[Replay]):
        if not replays:
            raise ConfigError("diagnose needs at least one record")
        kinds = {r.kind for r in replays}
        if len(kinds) > 1:
            raise ConfigError(f"records of one rig must be of one kind; got {', '.join(sorted(kinds))}")
        self.replays = sorted(replays, key=record_key)
        self.kind = replays[0].kind
        self.joint = len(replays) > 1
        # Free decays of one rig, each released and zeroed by hand: every record's encoder zero
        # is a nuisance of its own (real zeros differ by degrees; one shared zero, or none, leaves
        # a residual far above the encoder floor).
        self.nuisance = NUISANCE + (("theta_offset",) if self.joint and self.kind == "free_decay" else ())
        samples = np.array([len(r.eval_idx) * len(r.channels) for r in replays], dtype=float)
        self.floor = float(math.sqrt(np.sum(samples * [r.noise_floor() ** 2 for r in replays]) / samples.sum()))

    def key(self, param: str, i: int) -> str:
        return f"{param}@{i}" if self.joint else param

    def per_record(self, param: str) -> bool:
        return param in CHAIN_PARAMS or param in NUISANCE

    def record_values(self, values: dict[str, float], i: int) -> dict[str, float]:
        """The values record ``i`` is simulated with: shared ones and its own (suffix removed)."""
        out = {k: v for k, v in values.items() if "@" not in k}
        suffix = f"@{i}"
        out.update({k[: -len(suffix)]: v for k, v in values.items() if k.endswith(suffix)})
        return out

    def nominal_of(self, key: str) -> float:
        param, _, i = key.partition("@")
        rp = self.replays[int(i) if i else 0]
        return rp.nominal[param] if param in rp.nominal else rp.initial_guess[param]


@dataclass
class Fit:
    """One fitted model, cross-validated.

    Attributes
    ----------
    causes : tuple of str
        Vocabulary causes fitted together; empty for the nominal model.
    values, stderr : dict
        Fitted values on all compared samples and their one-sigma uncertainty
        (the larger of the Jacobian's, inflated for residual autocorrelation,
        and the fold jackknife's).
    error_fit, error_cv : float
        NRMSE of the fit on the compared samples and of the out-of-fold predictions.
    fold_values : list of dict
        The fitted values of every fold.
    block_mse : ndarray
        Mean squared normalised out-of-fold residual per block (all records' blocks).
    record_cv : list of float
        Out-of-fold NRMSE per record (the cross-record prediction error when several).
    bic : float
        Bayesian information criterion of the fit (reported, not used in the verdict).
    sims, oof : list of dict
        Per record: simulated channels of the fit; out-of-fold residuals (NaN where not compared).
    """

    causes: tuple[str, ...]
    values: dict[str, float]
    stderr: dict[str, float]
    error_fit: float
    error_cv: float
    fold_values: list[dict[str, float]]
    block_mse: np.ndarray = field(repr=False)
    record_cv: list[float]
    bic: float
    sims: list[dict[str, np.ndarray]] = field(repr=False, default_factory=list)
    oof: list[dict[str, np.ndarray]] = field(repr=False, default_factory=list)

    @property
    def cause(self) -> str | None:
        """The cause's name; two causes of a second round are joined by ``+``."""
        return "+".join(self.causes) or None

    @property
    def error_after(self) -> float:
        return self.error_cv

    @property
    def sim(self) -> dict[str, np.ndarray]:
        """Simulated channels of the first record."""
        return self.sims[0]

    @property
    def params(self) -> list[str]:
        return [EFFECTS[c].param for c in self.causes]

    def keys_of(self, cause: str) -> list[str]:
        p = EFFECTS[cause].param
        return [k for k in self.values if k == p or k.startswith(p + "@")]

    @property
    def estimate(self) -> dict[str, float]:
        return {k: self.values[k] for c in self.causes for k in self.keys_of(c)}

    @property
    def uncertainty(self) -> dict[str, float]:
        return {k: self.stderr[k] for c in self.causes for k in self.keys_of(c)}


def start_value(replay: Replay, eff) -> float:
    """Starting value of a candidate: the nominal, or a data-based guess.

    The effective length starts from the measured mean swing frequency so that
    single shooting does not lock onto a wrong number of cycles.
    """
    nominal = replay.nominal[eff.param]
    if eff.param == "l" and replay.kind == "free_decay":
        idx = replay.eval_idx
        theta = replay.meas["theta"][idx] - np.mean(replay.meas["theta"][idx])
        crossings = np.flatnonzero(np.diff(np.signbit(theta)))
        if len(crossings) >= 3:
            period = 2.0 * (crossings[-1] - crossings[0]) * replay.dt / (len(crossings) - 1)
            amp = np.max(np.abs(theta))
            # Large-amplitude period lengthening T = T0 (1 + A^2/16) of the pendulum, with A^2
            # taken as half the record's largest: the swing decays over the record. A start only
            # (1-1.4 % long at A = 0.5 rad on a slow decay); the fit refines it.
            omega0 = 2.0 * math.pi / period * (1.0 + amp * amp / 32.0)
            return float(np.clip(replay.nominal["g"] / omega0**2, eff.lower, 10.0))
    if eff.param == "theta_offset" and "theta" in replay.constant:
        # A hanging pendulum rests at theta = 0 (its only equilibrium at rest), so a constant
        # angle reading is the encoder zero itself. Started from 0, the fit must cross offsets
        # whose replayed pendulum starts far enough from rest to swing up (a forced pendulum near
        # its Hopf boundary), where least squares stalls.
        return float(replay.meas["theta"][0])
    if eff.param == "tau" and replay.kind == "substructured":
        # The delay starts from the measured lag of x behind its command (peak of the
        # cross-correlation, refined by a parabola): a start near the optimum saves
        # iterations of the closed-loop replay.
        x = replay.record.channel("y") - np.mean(replay.record.channel("y"))
        c = replay.command - np.mean(replay.command)
        k = max(2, int(0.05 / replay.dt))
        n = len(x)
        corr = np.array([float(x[j:] @ c[: n - j]) for j in range(k + 1)])
        j = int(np.clip(np.argmax(corr), 1, k - 1))
        den = corr[j - 1] - 2.0 * corr[j] + corr[j + 1]
        shift = 0.5 * (corr[j - 1] - corr[j + 1]) / den if den < 0 else 0.0
        return float(max((j + shift) * replay.dt, 0.0))
    return float(nominal)


def _params(problem: Problem, causes: tuple[str, ...], starts: dict[str, float]) -> list[_Param]:
    out = []
    for cause in causes:
        eff = effect(cause)
        records = range(len(problem.replays)) if problem.per_record(eff.param) else [None]
        for i in records:
            key = eff.param if i is None else problem.key(eff.param, i)
            if key not in starts:
                # A shared parameter starts from the median of the records' data-based starts:
                # the same start whatever the order of the records.
                own = [problem.replays[i]] if i is not None else problem.replays
                s0 = float(np.median([start_value(rp, eff) for rp in own]))
            else:
                s0 = starts[key]
            # trf's scaling freezes a variable that starts on its bound: start just inside.
            s0 = max(s0, eff.lower + 0.05 * eff.scale)
            out.append(_Param(key, i, s0, max(abs(s0), eff.scale), eff.lower, eff.upper))
    freed = {p.key for p in out}
    for i, rp in enumerate(problem.replays):
        if rp.fits_initial_state:
            for nm in problem.nuisance:
                key = problem.key(nm, i)
                if key in freed:  # the encoder zero, when a candidate (angle_offset) frees it already
                    continue
                guess = rp.initial_guess.get(nm, rp.nominal.get(nm, 0.0))
                out.append(_Param(key, i, starts.get(key, guess), _NUISANCE_SCALE[nm], -math.inf, math.inf))
    return out


def _solve(
    problem: Problem,
    params: list[_Param],
    objective: list[np.ndarray | None],
    fixed: dict[str, float],
    staged: bool = False,
) -> tuple[dict[str, float], np.ndarray | None, np.ndarray]:
    """Least squares of ``params`` on the samples ``objective[i]`` of each record (None: unused).

    Returns the values (``fixed`` included), the Jacobian in scaled units and the residuals.
    """
    start = np.array([p.start for p in params])
    scale = np.array([p.scale for p in params])
    keys = [p.key for p in params]

    def values_of(u: np.ndarray) -> dict[str, float]:
        return dict(fixed, **dict(zip(keys, start + scale * u)))

    def residual(u: np.ndarray, objective=objective) -> np.ndarray:
        vals = values_of(u)
        parts = []
        for i, (rp, idx) in enumerate(zip(problem.replays, objective)):
            if idx is None or len(idx) == 0:
                continue
            sim = rp.simulate(problem.record_values(vals, i), int(idx[-1]) + 1)
            parts.append(rp.residuals(sim, idx))
        r = np.concatenate(parts)
        return np.where(np.isfinite(r), r, _DIVERGED)

    u = np.zeros(len(params))
    jac = None
    if params:
        lo = (np.array([p.lower for p in params]) - start) / scale
        hi = (np.array([p.upper for p in params]) - start) / scale
        stages = [objective]
        if staged and problem.kind == "free_decay":
            # Fit a short prefix first so single shooting starts inside the right basin.
            stages.insert(0, [None if idx is None else idx[: max(len(idx) // 4, 10)] for idx in objective])
        for obj in stages:
            # A trial step can send the replay far off (huge residuals): its cost overflows to inf and
            # the step is rejected, which is the intended outcome, so numpy's overflow warning is noise.
            with np.errstate(over="ignore"):
                res = least_squares(
                    residual, u, args=(obj,), bounds=(lo, hi), method="trf", diff_step=1e-5, x_scale=1.0
                )
            u = res.x
        jac = res.jac
    return values_of(u), jac, residual(u)


def _jacobian_stderr(jac: np.ndarray, r: np.ndarray, params: list[_Param]) -> dict[str, float]:
    """Jacobian standard errors, inflated by (1 + rho)/(1 - rho) for residual autocorrelation rho."""
    n, k = jac.shape
    s2 = float(r @ r) / max(n - k, 1)
    rho = float(np.clip(np.corrcoef(r[:-1], r[1:])[0, 1], 0.0, 0.999)) if n > 3 and np.std(r) > 0 else 0.0
    cov = np.linalg.pinv(jac.T @ jac) * s2 * (1.0 + rho) / (1.0 - rho)
    return {p.key: float(p.scale * math.sqrt(max(c, 0.0))) for p, c in zip(params, np.diag(cov))}


def fit_model(
    problem: Problem | Replay,
    causes: tuple[str, ...] = (),
    starts: dict[str, float] | None = None,
    other_starts: tuple[dict[str, float], ...] = (),
) -> Fit:
    """Fit ``causes`` (and the per-record nuisances) on all compared samples, then cross-validate.

    ``starts`` gives starting values by key, e.g. the nominal fit's nuisance
    values, so that a candidate starts from the optimum it nests. Each of
    ``other_starts`` is tried too, and the fit with the least squared error on
    the compared samples is kept (the folds start from it).
    """
    if isinstance(problem, Replay):
        problem = Problem([problem])
    rps = problem.replays
    best = None
    objective = [rp.eval_idx for rp in rps]
    for start in (starts or {}, *other_starts):
        params = _params(problem, tuple(causes), start)
        zeros = [p for p in params if p.key.split("@")[0] == "theta_offset" and p.record is not None]
        zeros = [p for p in zeros if p.key not in start and "angle_offset" not in causes]
        if zeros:
            # Encoder zeros without a start: fit the rest with the zeros held first, so that the
            # zeros cannot absorb a wrong swing in the first iterations, then free them.
            movable = [p for p in params if p not in zeros]
            held, _, _ = _solve(problem, movable, objective, {p.key: p.start for p in zeros}, staged=True)
            params = _params(problem, tuple(causes), dict(start, **held))
        values, jac, r = _solve(problem, params, objective, {}, staged=not zeros)
        if best is None or float(r @ r) < float(best[3] @ best[3]):
            best = params, values, jac, r
    params, values, jac, r = best
    stderr = _jacobian_stderr(jac, r, params) if params else {}
    n = r.size
    bic = n * math.log(max(float(r @ r), 1e-300) / n) + len(params) * math.log(n)
    sims = [rp.simulate(problem.record_values(values, i)) for i, rp in enumerate(rps)]
    warm = [_Param(p.key, p.record, values[p.key], p.scale, p.lower, p.upper) for p in params]
    oof = [{c: np.full(rp.n, np.nan) for c in rp.channels} for rp in rps]
    fold_values: list[dict[str, float]] = []

    def store(i: int, sim: dict[str, np.ndarray], idx: np.ndarray) -> None:
        for c in rps[i].channels:
            oof[i][c][idx] = (sim[c][idx] - rps[i].meas[c][idx]) / rps[i].scale[c]

    if not params:
        for i, rp in enumerate(rps):
            store(i, sims[i], rp.eval_idx)
    elif not problem.joint:
        # Fold refits by one Gauss-Newton step from the full fit on the fold's
        # training rows (exact for a residual linear in the parameters, and the
        # residual is nearly linear over a fold-to-fold change).
        rp = rps[0]
        rows = np.tile(rp.eval_idx, len(rp.channels))
        scale = np.array([p.scale for p in params])
        lower = np.array([p.lower for p in params])
        upper = np.array([p.upper for p in params])
        full = np.array([values[p.key] for p in params])
        for k in range(rp.folds):
            keep = ~np.isin(rows, rp.fold_indices(k))
            step = np.linalg.lstsq(jac[keep], -r[keep], rcond=None)[0]
            vals = dict(zip([p.key for p in params], np.clip(full + scale * step, lower, upper)))
            fold_values.append(vals)
            store(0, rp.simulate(vals), rp.fold_indices(k))
    else:
        for i, rp in enumerate(rps):
            others = [p for p in warm if p.record != i]
            own = [p for p in warm if p.record == i]
            vals, _, _ = _solve(problem, others, [None if j == i else q.eval_idx for j, q in enumerate(rps)], {})
            if own:
                vals, _, _ = _solve(
                    problem,
                    own,
                    [rp.eval_idx if j == i else None for j in range(len(rps))],
                    {k: v for k, v in vals.items()},
                )
            fold_values.append(vals)
            store(i, rp.simulate(problem.record_values(vals, i)), rp.eval_idx)
    for p in params:
        # Delete-a-group jackknife over the folds that fitted p.
        reps = np.array([fv[p.key] for fv in fold_values if p.key in fv and (p.record is None or not problem.joint)])
        if len(reps) >= 2:
            jk = math.sqrt((len(reps) - 1) / len(reps) * float(np.sum((reps - reps.mean()) ** 2)))
            stderr[p.key] = max(stderr[p.key], jk)
        # An encoder zero read off resting (constant) angles is known to the reading's quantisation
        # at best, however well the fit reproduces the level.
        stderr[p.key] = max(stderr[p.key], _resting_level_sigma(problem, p.key))
    block_mse, record_cv, sq_all = [], [], []
    for i, rp in enumerate(rps):
        # Compared samples of a diverged prediction are NaN: infinite error there.
        sq = np.mean([oof[i][c] ** 2 for c in rp.channels], axis=0)
        sq[rp.eval_idx] = np.where(np.isfinite(sq[rp.eval_idx]), sq[rp.eval_idx], math.inf)
        block_mse += [float(np.mean(sq[b])) for b in rp.blocks]
        record_cv.append(float(math.sqrt(np.mean(sq[rp.eval_idx]))))
        sq_all.append(sq[rp.eval_idx])
    sq_all = np.concatenate(sq_all)
    error_cv = float(math.sqrt(np.mean(sq_all)))
    fit_sq = np.concatenate([rp.residuals(sims[i], rp.eval_idx) ** 2 for i, rp in enumerate(rps)])
    error_fit = float(math.sqrt(np.mean(fit_sq))) if np.all(np.isfinite(fit_sq)) else math.inf
    return Fit(
        tuple(causes), values, stderr, error_fit, error_cv, fold_values, np.array(block_mse), record_cv, bic, sims, oof
    )


def _score(problem: Problem, fit: Fit, cause: str) -> float:
    """Score test: the squared-error reduction one Gauss-Newton step on ``cause`` would give from ``fit``.

    Ranks the partners of a second round by one finite-difference Jacobian
    column each instead of a full fit.
    """
    eff = effect(cause)
    base = dict(fit.values)
    keys = (
        [problem.key(eff.param, i) for i in range(len(problem.replays))]
        if problem.per_record(eff.param)
        else [eff.param]
    )
    moved = dict(base)
    for k in keys:
        v = base.get(k, problem.nominal_of(k))
        base[k] = v
        moved[k] = v + 1e-4 * max(abs(v), eff.scale)
    r0, r1 = [], []
    for i, rp in enumerate(problem.replays):
        r0.append(rp.residuals(rp.simulate(problem.record_values(base, i)), rp.eval_idx))
        r1.append(rp.residuals(rp.simulate(problem.record_values(moved, i)), rp.eval_idx))
    r0, r1 = np.concatenate(r0), np.concatenate(r1)
    j = r1 - r0
    if not (np.all(np.isfinite(j)) and np.all(np.isfinite(r0))) or j @ j == 0:
        return 0.0
    return float((j @ r0) ** 2 / (j @ j))


def _rank(fit: Fit) -> tuple[float, float, str]:
    """Ranking key of candidates: cross-validated error, then BIC, then the name (deterministic ties)."""
    return fit.error_cv, fit.bic, fit.cause or ""


def block_test(before: Fit, after: Fit) -> float:
    """One-sided p value that ``after`` predicts the held-out blocks better than ``before``.

    Wilcoxon signed-rank test on the blocks' differences of out-of-fold mean
    squared error; zero differences (e.g. blocks where both models are exact)
    are split between the signs instead of being dropped or breaking the test.
    """
    fb, fa = np.isfinite(before.block_mse), np.isfinite(after.block_mse)
    with np.errstate(invalid="ignore"):
        d = before.block_mse - after.block_mse
    if not np.all(fb & fa):
        # A model that diverges on a block is the worse one there (largest rank); both diverging: a tie.
        big = 2.0 * float(np.max(np.abs(d[fb & fa]), initial=1.0))
        d = np.where(fb & fa, d, np.where(fa, big, np.where(fb, -big, 0.0)))
    if np.all(d == 0.0):
        return 1.0
    return float(stats.wilcoxon(d, zero_method="zsplit", alternative="greater").pvalue)


def _resting_level_sigma(problem: Problem, key: str) -> float:
    """Quantisation sigma of an encoder zero ``key`` read off resting angle levels only (else 0)."""
    if key.split("@")[0] != "theta_offset":
        return 0.0
    records = [problem.replays[int(key.split("@")[1])]] if "@" in key else problem.replays
    return REST_LEVEL_SIGMA if all(rp.rests for rp in records) else 0.0


def _quantisation_bounded(problem: Problem, fit: Fit, key: str) -> bool:
    """Whether ``key``'s uncertainty in ``fit`` is the bounded quantisation of resting angle levels."""
    sigma = _resting_level_sigma(problem, key)
    return sigma > 0.0 and fit.stderr[key] <= sigma


def _z_needed(problem: Problem, fit: Fit, cause: str) -> float:
    """The z a cause's parameters must reach: Z_BOUNDED where every one is quantisation-bounded."""
    bounded = all(_quantisation_bounded(problem, fit, k) for k in fit.keys_of(cause))
    return Z_BOUNDED if bounded else Z_MIN


def _z(problem: Problem, fit: Fit, cause: str) -> tuple[float, bool]:
    """Smallest |change from nominal| / uncertainty over the cause's parameters, and whether every
    fold changed the parameter in the same direction as the full fit."""
    zs, stable = [], True
    for k in fit.keys_of(cause):
        nominal = problem.nominal_of(k)
        change = fit.values[k] - nominal
        se = fit.stderr.get(k, math.inf)
        zs.append(abs(change) / se if se > 0 else math.inf)
        folds = [fv[k] - nominal for fv in fit.fold_values if k in fv]
        stable &= all(np.sign(f) == np.sign(change) for f in folds)
    return (min(zs) if zs else 0.0), stable


def channel_ratios(problem: Problem, fit: Fit) -> dict[str, float]:
    """Per sensor channel: cross-validated mean square / the channel's noise variance (largest over records)."""
    out: dict[str, float] = {}
    for i, rp in enumerate(problem.replays):
        for c in rp.channels:
            if c in EXACT_CHANNELS or c in rp.constant:
                # A constant channel has no noise of its own: its level error counts in the pooled ratio,
                # where its zero noise adds nothing to the floor.
                continue
            ms = float(np.mean(fit.oof[i][c][rp.eval_idx] ** 2))
            noise2 = (rp.noise[c] / rp.scale[c]) ** 2
            ratio = ms / noise2 if noise2 > 0 else math.inf
            out[c] = max(out.get(c, 0.0), ratio if math.isfinite(ms) else math.inf)
    return out


def structured_residual(problem: Problem, fit: Fit, pooled_ratio: float) -> bool:
    """Whether ``fit`` leaves more than noise: pooled error^2 above ``pooled_ratio x floor^2``, or
    (kinds in :data:`CHANNEL_RATIO`) one sensor channel above ``CHANNEL_RATIO x`` its noise variance."""
    if fit.error_cv**2 > pooled_ratio * problem.floor**2:
        return True
    limit = CHANNEL_RATIO.get(problem.kind)
    return limit is not None and any(r > limit for r in channel_ratios(problem, fit).values())


def implausible(problem: Problem, fit: Fit) -> list[str]:
    """Why ``fit``'s estimates are physically implausible (empty when they are not): a parameter more
    than :data:`IMPLAUSIBLE_FACTOR` times its nonzero nominal."""
    out = []
    for c in fit.causes:
        for k in fit.keys_of(c):
            nominal, value = problem.nominal_of(k), fit.values[k]
            if nominal != 0.0 and abs(value) > IMPLAUSIBLE_FACTOR * abs(nominal):
                out.append(
                    f"{c}: estimate {value:.3g} is {value / nominal:.3g} x its nominal {nominal:.3g}, "
                    f"beyond {IMPLAUSIBLE_FACTOR:g} x (physically implausible)"
                )
    return out


def _judge(problem: Problem, base: Fit, model: Fit, share_min: float, causes: tuple[str, ...]) -> dict[str, Any]:
    """The three tests of ``model`` against ``base``; ``passed`` says whether all hold."""
    floor2 = problem.floor**2
    excess = base.error_cv**2 - floor2
    reduction = base.error_cv**2 - model.error_cv**2
    share = reduction / excess if excess > 0 and math.isfinite(reduction) else 0.0
    p = block_test(base, model) if math.isfinite(model.error_cv) else 1.0
    zs = {c: _z(problem, model, c) for c in causes}
    needed = {c: _z_needed(problem, model, c) for c in causes}
    passed = (
        share >= share_min
        and reduction > FLOOR_SHARE * floor2
        and p < P_VALUE
        and all(z >= needed[c] and stable for c, (z, stable) in zs.items())
    )
    return {
        "model": model.cause,
        "against": base.cause or "nominal",
        "explained_share": share,
        "share_needed": share_min,
        "reduction": reduction,
        "reduction_needed": FLOOR_SHARE * floor2,
        "p_value": p,
        "p_needed": P_VALUE,
        "z": {c: z for c, (z, _) in zs.items()},
        "z_needed": needed,
        "folds_agree": {c: s for c, (_, s) in zs.items()},
        "passed": bool(passed),
    }


def failed_tests(judgement: dict[str, Any]) -> list[str]:
    """The tests of one :func:`_judge` result that failed, in words (empty when it passed)."""
    j, out = judgement, []
    against = j["against"]
    if j["explained_share"] < j["share_needed"]:
        out.append(
            f"explains {j['explained_share']:.2f} of {against}'s excess squared error, {j['share_needed']:g} needed"
        )
    if not j["reduction"] > j["reduction_needed"]:
        out.append(f"reduction {j['reduction']:.3g} of {against}'s squared error below {j['reduction_needed']:.3g}")
    if not j["p_value"] < j["p_needed"]:
        out.append(f"block test against {against}: p = {j['p_value']:.2g}, below {j['p_needed']:g} needed")
    for c, z in j["z"].items():
        if not z >= j["z_needed"][c]:
            out.append(
                f"{c}: change from nominal only {z:.2f} of its fit uncertainty (jackknife over the folds), "
                f"{j['z_needed'][c]:.3g} needed"
            )
        if not j["folds_agree"][c]:
            out.append(f"{c}: the folds disagree on the direction of the change")
    if j.get("chain_ok") is False:
        out.append("does not beat its single cause with the actuator delay freed (absorbs model-form error)")
    return out


@dataclass
class Diagnosis:
    """Nominal comparison, ranked candidates, verdict and what remains, for one or several records."""

    problem: Problem
    nominal: Fit
    candidates: list[Fit]
    cause: str
    tests: dict[str, Any]

    @property
    def replay(self) -> Replay:
        return self.problem.replays[0]

    @property
    def noise_floor(self) -> float:
        return self.problem.floor

    @property
    def best(self) -> Fit | None:
        return next((c for c in self.candidates if c.cause == self.cause), None)

    @property
    def verdict_fit(self) -> Fit:
        return self.best or self.nominal

    @property
    def error_after(self) -> float:
        return self.verdict_fit.error_cv

    @property
    def explained_share(self) -> float:
        """Share of the nominal model's excess squared error (above the noise floor) the verdict removes."""
        excess = self.nominal.error_cv**2 - self.noise_floor**2
        if self.best is None or excess <= 0:
            return 0.0
        return float(np.clip((self.nominal.error_cv**2 - self.error_after**2) / excess, 0.0, 1.0))

    def status(self, fit: Fit) -> tuple[str, list[str]]:
        """Whether ``fit`` was named, rejected (and which tests failed) or not judged (and why)."""
        if fit.cause == self.cause:
            return "named", []
        if fit.cause in self.tests.get("implausible", {}):
            return "rejected", self.tests["implausible"][fit.cause]
        first, second = self.tests.get("first_round"), self.tests.get("second_round")
        for j in (first, second):
            if j is not None and j["model"] == fit.cause:
                reasons = failed_tests(j)
                if j is second and not j["against_nominal_passed"]:
                    reasons += [
                        r + " (against nominal)"
                        for r in failed_tests(self.tests["second_against_nominal"])
                        if r not in reasons
                    ]
                if not reasons and self.cause != "none":
                    reasons = [f"passed, but {self.cause} was named after it"]
                return "rejected", reasons
        if len(fit.causes) == 1:
            best = first["model"] if first else None
            return "not judged", [f"only the best single cause ({best}) is tested in the first round"]
        best = second["model"] if second else None
        return "not judged", [f"only the best pair ({best}) is tested in the second round"]

    def second_round_note(self) -> str:
        """Whether pairs were tried, and why not when they were not."""
        if "second_round" in self.tests:
            return "run"
        return "not run: the best single cause leaves no structured residual (or only one candidate)"

    def tied_with(self) -> list[str]:
        """Causes (of the verdict's round) that predict the held-out blocks about as well as the verdict.

        A candidate of as many causes as the verdict's, with plausible estimates, that explains at
        least :data:`SHARE_MIN` of the nominal's excess, and that the verdict does not beat on the
        held-out blocks (one-sided signed-rank test, p >= :data:`P_VALUE`): the data do not tell
        them apart, whatever the ranking by cross-validated error says.
        """
        best = self.best
        if best is None:
            return []
        excess = self.nominal.error_cv**2 - self.noise_floor**2
        out = []
        for c in self.candidates:
            if c is best or len(c.causes) != len(best.causes) or not math.isfinite(c.error_cv):
                continue
            if c.cause in self.tests.get("implausible", {}) or excess <= 0:
                continue
            share = (self.nominal.error_cv**2 - c.error_cv**2) / excess
            if share >= SHARE_MIN and block_test(c, best) >= P_VALUE:
                out.append(c.cause)
        return out

    @property
    def unexplained(self) -> bool:
        """The verdict model's residual is well above the noise: pooled, or in one sensor channel."""
        return structured_residual(self.problem, self.verdict_fit, UNEXPLAINED_RATIO[self.problem.kind])

    def validation(self) -> dict[str, Any]:
        rps = self.problem.replays
        if self.problem.joint:
            return {
                "method": "leave-one-record-out",
                "records": [rp.record.name for rp in rps],
                "cross_record_error_nominal": self.nominal.record_cv,
                "cross_record_error": self.verdict_fit.record_cv,
            }
        rp = rps[0]
        return {
            "method": "blocked cross-validation",
            "folds": rp.folds,
            "blocks": len(rp.blocks),
            "block_seconds": float(np.mean([len(b) for b in rp.blocks]) * rp.dt),
            "compared_seconds": float(len(rp.eval_idx) * rp.dt),
            "record_seconds": float(rp.n * rp.dt),
            "constant_channels": list(rp.constant),
        }

    def stated_uncertainty(self, fit: Fit) -> dict[str, float]:
        """One-sigma uncertainty of ``fit``'s estimates as reported: its own, calibrated by kind.

        The fit's own uncertainty (``Fit.uncertainty``) is what the verdict's
        tests divide by; see :data:`UNCERTAINTY_CALIBRATION`. A resting encoder
        zero whose uncertainty is the quantisation bound keeps it: the bound is
        exact, the calibration is for model-form error.
        """
        factor = UNCERTAINTY_CALIBRATION[self.problem.kind]
        return {k: v if _quantisation_bounded(self.problem, fit, k) else factor * v for k, v in fit.uncertainty.items()}

    def to_json(self) -> dict[str, Any]:
        """cause, estimate, uncertainty, error_before/after, gain, explained_share, unexplained, ..."""
        from .signatures import residual_signature

        best = self.best
        before = self.nominal.error_cv
        return {
            "cause": self.cause,
            "estimate": best.estimate if best else {},
            "uncertainty": self.stated_uncertainty(best) if best else {},
            "fit_uncertainty": best.uncertainty if best else {},
            "error_before": before,
            "error_after": self.error_after,
            "gain": 1.0 - self.error_after / before if best and before > 0 else 0.0,
            "explained_share": self.explained_share,
            "unexplained": self.unexplained,
            "tied_with": self.tied_with(),
            "residual_to_noise": channel_ratios(self.problem, self.verdict_fit),
            "noise_floor": self.noise_floor,
            "validation": self.validation(),
            "residual_signature": residual_signature(self.problem, self.verdict_fit),
            "candidates": [
                dict(
                    zip(("status", "reasons"), self.status(c)),
                    cause=c.cause,
                    estimate=c.estimate,
                    uncertainty=self.stated_uncertainty(c),
                    fit_uncertainty=c.uncertainty,
                    error_after=c.error_cv,
                    cross_record_error=c.record_cv if self.problem.joint else None,
                    bic=c.bic,
                )
                for c in self.candidates
            ],
            "second_round": self.second_round_note(),
            "nuisance": {k: v for k, v in self.verdict_fit.values.items() if k.split("@")[0] in self.problem.nuisance},
        }


def diagnose(replays: Replay | list[Replay], causes: list[str] | None = None, n_jobs: int = 1) -> Diagnosis:
    """Fit the nominal model and every applicable candidate; return the verdict.

    Parameters
    ----------
    replays : Replay or list of Replay
        One record, or several records of one rig (fitted jointly).
    causes : list of str, optional
        Restrict the candidates (default: all applicable to the records' kind).
    n_jobs : int
        Candidates fitted in parallel (threads; the kernels release the GIL).
    """
    # The fits' tall, thin SVDs run several times faster on one BLAS thread than on an
    # oversubscribed pool (candidates are parallelised by joblib instead).
    with threadpool_limits(1, user_api="blas"):
        return _diagnose(Problem(replays if isinstance(replays, list) else [replays]), causes, n_jobs)


def _pair_starts(problem: Problem, single: Fit, partner: Fit) -> tuple[dict[str, float], ...]:
    """Further starts of the pair ``single + partner`` on several records: from the partner's own
    fit, and from both singles' values together.

    A joint fit of several releases of a stick-slip pendulum has more than one
    minimum (on the three real records the length plus Coulomb friction reached
    cross-record errors from 0.35 to 1.0 by start alone); the pair's fit must not
    depend on which of its two causes ranked first.
    """
    if not problem.joint:
        return ()
    own = {k: partner.values[k] for c in partner.causes for k in partner.keys_of(c)}
    return _without_zeros(partner.values), _without_zeros(dict(single.values, **own))


def _without_zeros(values: dict[str, float]) -> dict[str, float]:
    """``values`` less the per-record encoder zeros (a fit starting from them fits the zeros last)."""
    return {k: v for k, v in values.items() if not k.startswith("theta_offset@")}


def _diagnose(problem: Problem, causes: list[str] | None, n_jobs: int) -> Diagnosis:
    allowed = [e.cause for e in applicable(problem.kind)]
    # A cause whose parameter is already a nuisance of every model is no candidate by default.
    default = [c for c in allowed if EFFECTS[c].param not in problem.nuisance]
    causes = default if causes is None else list(causes)
    bad = [c for c in causes if c not in allowed]
    if bad:
        raise ConfigError(
            f"cause(s) {', '.join(bad)} do not apply to kind {problem.kind!r}; applicable: {', '.join(allowed)}"
        )
    nominal = fit_model(problem)
    # Candidates start from the nominal model's initial states fitted with the encoder zeros held
    # (freed zeros absorb what they can of the nominal model's error and shift the initial states;
    # fit_model frees the zeros after the rest).
    initial = nominal.values
    if "theta_offset" in problem.nuisance:
        params = _params(problem, (), {})
        held = [p for p in params if p.key.split("@")[0] == "theta_offset"]
        initial, _, _ = _solve(
            problem,
            [p for p in params if p not in held],
            [rp.eval_idx for rp in problem.replays],
            {p.key: p.start for p in held},
            staged=True,
        )
    nuisance = {k: v for k, v in initial.items() if k.split("@")[0] in NUISANCE}
    # Fitted initial states of a wrong model can be nonsense (a free decay whose period is 3 % off
    # drifts a cycle over 45 swings, and the nominal fit then settles on a swing of 0.02 rad where
    # the data start at 0.5): candidates also start from the data's own initial states, and the
    # better fit is kept.
    data_start = ({},) if any(rp.fits_initial_state for rp in problem.replays) else ()
    pool = Parallel(n_jobs=n_jobs, prefer="threads")
    fits = pool(delayed(fit_model)(problem, (c,), nuisance, data_start) for c in causes)
    tests: dict[str, Any] = {"noise_floor": problem.floor}
    verdict = "none"
    # A cause whose estimate is physically implausible is absorbing something else: it is not named,
    # nor started from in the second round (its status says why).
    tests["implausible"] = {f.cause: r for f in fits if (r := implausible(problem, f))}
    plausible = [f for f in fits if f.cause not in tests["implausible"]]
    first = min(plausible, key=_rank) if plausible else None
    if first is not None:
        tests["first_round"] = _judge(problem, nominal, first, SHARE_MIN, first.causes)
        if tests["first_round"]["passed"]:
            verdict = first.cause
    # Second round from the BEAM best single causes (named or not: a single
    # effect may fail the tests when a second one is present, and the best
    # single cause of a two-effect record need not be one of the two).
    if first is not None and len(causes) > 1 and structured_residual(problem, first, SECOND_ROUND_RATIO):
        singles = {f.causes[0]: f for f in fits}
        ranked = sorted(plausible, key=_rank)[:BEAM]
        jobs, tests["partner_scores"] = [], {}
        for single in ranked:
            others = [c for c in causes if c != single.cause]
            scores = dict(zip(others, pool(delayed(_score)(problem, single, c) for c in others)))
            partners = sorted(others, key=lambda c: -scores[c])[:PARTNERS]
            if problem.kind == "substructured" and "actuator_delay" in others and "actuator_delay" not in partners:
                partners.append("actuator_delay")  # its data-based start matters more than a local score
            tests["partner_scores"][single.cause] = scores
            jobs += [
                (single, c) for c in partners if not any({single.cause, c} == set(s.causes) | {p} for s, p in jobs)
            ]
        pairs = pool(
            delayed(fit_model)(
                problem,
                s.causes + (c,),
                _without_zeros(dict(nuisance, **s.values)),
                _pair_starts(problem, s, singles[c]),
            )
            for s, c in jobs
        )
        tests["implausible"].update({f.cause: r for f in pairs if (r := implausible(problem, f))})
        pair = min([f for f in pairs if f.cause not in tests["implausible"]] or pairs, key=_rank)
        # Judged against the better of its own two single causes.
        base = min((singles[c] for c in pair.causes), key=_rank)
        second = _judge(problem, base, pair, SECOND_SHARE_MIN, pair.causes)
        against_nominal = _judge(problem, nominal, pair, SHARE_MIN, pair.causes)
        second["against_nominal_passed"] = against_nominal["passed"]
        tests["second_against_nominal"] = against_nominal
        chain_ok = True
        with_delay = [f for f in pairs if set(f.causes) == {base.cause, "actuator_delay"}]
        if with_delay and "actuator_delay" not in pair.causes:
            # The pair must beat its single cause with the actuator's delay freed:
            # otherwise the second parameter is soaking up the actuator's model-form error.
            chained = with_delay[0]
            second["chain_check"] = {"single_with_delay_error": chained.error_cv, "pair_error": pair.error_cv}
            chain_ok = pair.error_cv**2 < chained.error_cv**2 - 0.5 * (base.error_cv**2 - pair.error_cv**2)
        second["chain_ok"] = chain_ok
        tests["second_round"] = second
        if second["passed"] and against_nominal["passed"] and chain_ok and pair.cause not in tests["implausible"]:
            verdict = pair.cause
        fits += pairs
    fits.sort(key=_rank)
    return Diagnosis(problem, nominal, fits, verdict, tests)
