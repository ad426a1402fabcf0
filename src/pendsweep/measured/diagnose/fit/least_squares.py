"""The fit stage's least squares: the problem over one or several replays, one model's fit, its cross-validation and uncertainties."""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ....errors import ConfigError
from ..effects import CHAIN_PARAMS, EFFECTS, effect
from ..identify.transfer import lag_of
from ..replay.whole import REST_LEVEL_SIGMA, Replay

#: Channels recorded exactly (the controller's own command): no sensor noise to compare with.
EXACT_CHANNELS = ("y_cmd",)
#: Scales of the free-decay nuisance parameters [rad], [rad/s].
_NUISANCE_SCALE = {"theta_offset": 0.01}
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
        self.nuisance = self.replays[0].nuisance + (
            ("theta_offset",) if self.joint and self.kind == "free_decay" else ()
        )
        samples = np.array([len(r.eval_idx) * len(r.channels) for r in replays], dtype=float)
        self.floor = float(math.sqrt(np.sum(samples * [r.noise_floor() ** 2 for r in replays]) / samples.sum()))

    def key(self, param: str, i: int) -> str:
        return f"{param}@{i}" if self.joint else param

    def per_record(self, param: str) -> bool:
        return param in CHAIN_PARAMS or param in self.nuisance

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
    block_chi2 : ndarray or None
        The same in units of each channel's noise (:func:`_whitened_square`).
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
    block_chi2: np.ndarray | None = field(repr=False, default=None)

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
        return lag_of(replay.command, replay.record.channel("y"), replay.dt, max_lag=0.05)
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
        for nm in problem.nuisance:
            key = problem.key(nm, i)
            if key in freed:  # the encoder zero, when a candidate (angle_offset) frees it already
                continue
            guess = rp.initial_guess.get(nm, rp.nominal.get(nm, 0.0))
            scale = rp.nuisance_scale.get(nm, _NUISANCE_SCALE.get(nm, 1.0))
            lower, upper = rp.nuisance_bounds.get(nm, (-math.inf, math.inf))
            out.append(_Param(key, i, starts.get(key, guess), scale, lower, upper))
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
            parts.append(rp.fit_residuals(sim, idx))
        r = np.concatenate(parts)
        # A replay that diverged (non-finite) or nearly so (a trial far outside the physics: 1e147 was
        # seen) is as wrong as can be; bounded, it leaves the trust region's arithmetic finite.
        return np.where(np.isfinite(r), np.clip(r, -_DIVERGED, _DIVERGED), _DIVERGED)

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
    ``other_starts`` is tried too (a start the record points to, see
    :mod:`..identify.oscillator`; the objective may hold several basins). On one record
    the fit with the least cross-validated error is kept (the held-out
    blocks decide, ties by the squared error on the compared samples); on
    several records the one with the least squared error (each start's
    leave-one-record-out refits would multiply the cost by the records).
    """
    if isinstance(problem, Replay):
        problem = Problem([problem])
    solved = [_solve_from(problem, tuple(causes), start) for start in (starts or {}, *other_starts)]
    if problem.joint or len(solved) == 1:
        return _cross_validate(problem, tuple(causes), *min(solved, key=lambda s: float(s[3] @ s[3])))
    fits = [_cross_validate(problem, tuple(causes), *s) for s in solved]
    return min(zip(fits, solved), key=lambda fs: (fs[0].error_cv, float(fs[1][3] @ fs[1][3])))[0]


def _solve_from(problem: Problem, causes: tuple[str, ...], start: dict[str, float]):
    """The least-squares fit of ``causes`` from ``start``: its parameters, values, Jacobian and residuals."""
    objective = [rp.eval_idx for rp in problem.replays]
    params = _params(problem, causes, start)
    zeros = [p for p in params if p.key.split("@")[0] == "theta_offset" and p.record is not None]
    zeros = [p for p in zeros if p.key not in start and "angle_offset" not in causes]
    if zeros:
        # Encoder zeros without a start: fit the rest with the zeros held first, so that the
        # zeros cannot absorb a wrong swing in the first iterations, then free them.
        movable = [p for p in params if p not in zeros]
        held, _, _ = _solve(problem, movable, objective, {p.key: p.start for p in zeros}, staged=True)
        params = _params(problem, causes, dict(start, **held))
    values, jac, r = _solve(problem, params, objective, {}, staged=not zeros)
    return params, values, jac, r


def _cross_validate(
    problem: Problem, causes: tuple[str, ...], params: list[_Param], values: dict[str, float], jac, r: np.ndarray
) -> Fit:
    """The :class:`Fit` of a solved model: its uncertainties, out-of-fold predictions and block errors."""
    rps = problem.replays
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
    block_mse, block_chi2, record_cv, sq_all = [], [], [], []
    for i, rp in enumerate(rps):
        # Compared samples of a diverged prediction are NaN: infinite error there (and a prediction far
        # off overflows its square to inf, the same verdict).
        with np.errstate(over="ignore"):
            sq = np.mean([oof[i][c] ** 2 for c in rp.channels], axis=0)
        sq[rp.eval_idx] = np.where(np.isfinite(sq[rp.eval_idx]), sq[rp.eval_idx], math.inf)
        chi2 = _whitened_square(rp, oof[i])
        block_mse += [float(np.mean(sq[b])) for b in rp.blocks]
        block_chi2 += [float(np.mean(chi2[b])) for b in rp.blocks]
        record_cv.append(float(math.sqrt(np.mean(sq[rp.eval_idx]))))
        sq_all.append(sq[rp.eval_idx])
    sq_all = np.concatenate(sq_all)
    error_cv = float(math.sqrt(np.mean(sq_all)))
    fit_sq = np.concatenate([rp.residuals(sims[i], rp.eval_idx) ** 2 for i, rp in enumerate(rps)])
    error_fit = float(math.sqrt(np.mean(fit_sq))) if np.all(np.isfinite(fit_sq)) else math.inf
    return Fit(
        causes, values, stderr, error_fit, error_cv, fold_values, np.array(block_mse), record_cv, bic, sims, oof,
        np.array(block_chi2),
    )  # fmt: skip


def _whitened_square(rp: Replay, oof: dict[str, np.ndarray]) -> np.ndarray:
    """Per sample, the mean over a record's noisy channels of the squared out-of-fold residual in units
    of that channel's noise (inf where a prediction diverged; NaN where nothing is compared).

    The pooled error weights a channel by its spread, so a channel that barely moves (a small
    pendulum's angle, a few encoder steps) dominates it with its own noise, and a look-alike that
    misses the other channel by many times that channel's noise looks as good as the truth.
    Channels without noise of their own (constant, or exact) are left out.
    """
    noisy = [c for c in rp.channels if rp.noise[c] > 0 and c not in EXACT_CHANNELS]
    if not noisy:
        return np.full(rp.n, np.nan)
    with np.errstate(over="ignore"):  # a prediction far off: an infinite error, as a diverged one
        chi2 = np.mean([(oof[c] * rp.scale[c] / rp.noise[c]) ** 2 for c in noisy], axis=0)
    compared = rp.moving.copy()
    chi2[compared] = np.where(np.isfinite(chi2[compared]), chi2[compared], math.inf)
    return chi2


def _resting_level_sigma(problem: Problem, key: str) -> float:
    """Quantisation sigma of an encoder zero ``key`` read off resting angle levels only (else 0)."""
    if key.split("@")[0] != "theta_offset":
        return 0.0
    records = [problem.replays[int(key.split("@")[1])]] if "@" in key else problem.replays
    return REST_LEVEL_SIGMA if all(rp.rests for rp in records) else 0.0
