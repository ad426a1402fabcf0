"""Least-squares fits of candidate effects, their ranking and the verdict.

Every candidate frees one vocabulary parameter (plus, on free decays, the
initial angle and velocity, which are nuisance parameters of every model,
the nominal included) and is fitted with :func:`scipy.optimize.least_squares`
on the training part. Candidates are ranked by held-out NRMSE; BIC on the
training part is reported next to it.

Verdict: the best candidate is named only when all three hold

1. its held-out error reduction exceeds the noise floor's share,
   ``error_before^2 - error_after^2 > FLOOR_SHARE * floor^2``, where
   ``floor`` is the sensor-noise NRMSE estimated from the data;
2. the reduction is consistent along the held-out part: a one-sided t test
   over ``BLOCKS`` contiguous blocks of the log ratio of mean squared errors
   gives p < ``P_VALUE``;
3. BIC improves on the nominal by more than ``DELTA_BIC`` (strong evidence).

Otherwise the verdict is ``none``. When the best single cause leaves a held-out
error above ``SECOND_ROUND_FLOOR`` x floor, a greedy second round fits it
together with each other candidate and names the best pair (``"a+b"``) when
the pair passes the same three tests against that single cause and against
the nominal model, and removes more than ``SECOND_ROUND_SHARE`` of the single
cause's squared error above the floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from joblib import Parallel, delayed
from scipy import stats
from scipy.optimize import least_squares

from ..errors import ConfigError
from .effects import EFFECTS, Effect, applicable, effect
from .replay import NUISANCE, Replay

FLOOR_SHARE = 0.25
BLOCKS = 10
P_VALUE = 0.01
DELTA_BIC = 10.0
#: The second round runs when the best single cause leaves more than this multiple of the floor ...
SECOND_ROUND_FLOOR = 1.5
#: ... and names a pair that removes more than this share of the single cause's excess over the floor.
SECOND_ROUND_SHARE = 0.5
#: Scales of the free-decay nuisance parameters [rad], [rad/s].
_NUISANCE_SCALE = {"theta_init": 0.01, "thetadot_init": 0.05}
_DIVERGED = 1e3


@dataclass
class Fit:
    """One fitted model.

    Attributes
    ----------
    causes : tuple of str
        Vocabulary causes fitted together; empty for the nominal model.
    values : dict
        Every fitted value (the causes' parameters and nuisance parameters).
    stderr : dict
        One-sigma uncertainty of each fitted value.
    error_train, error_after : float
        NRMSE on the training and held-out parts.
    bic : float
        Bayesian information criterion on the training part.
    sim : dict
        Simulated channels over the whole record.
    """

    causes: tuple[str, ...]
    values: dict[str, float]
    stderr: dict[str, float]
    error_train: float
    error_after: float
    bic: float
    sim: dict[str, np.ndarray] = field(repr=False, default_factory=dict)

    @property
    def cause(self) -> str | None:
        """The cause's name; two causes of a second round are joined by ``+``."""
        return "+".join(self.causes) or None

    @property
    def params(self) -> list[str]:
        return [EFFECTS[c].param for c in self.causes]

    @property
    def estimate(self) -> dict[str, float]:
        return {p: self.values[p] for p in self.params}

    @property
    def uncertainty(self) -> dict[str, float]:
        return {p: self.stderr[p] for p in self.params}


def start_value(replay: Replay, eff: Effect) -> float:
    """Starting value of a candidate: the nominal, or a data-based guess.

    The effective length starts from the measured mean swing frequency so that
    single shooting does not lock onto a wrong number of cycles.
    """
    nominal = replay.nominal[eff.param]
    if eff.param == "l" and replay.kind == "free_decay":
        theta = replay.meas["theta"] - np.mean(replay.meas["theta"])
        crossings = np.flatnonzero(np.diff(np.signbit(theta)))
        if len(crossings) >= 3:
            period = 2.0 * (crossings[-1] - crossings[0]) * replay.dt / (len(crossings) - 1)
            amp = np.max(np.abs(theta))
            # Large-amplitude period lengthening T = T0 (1 + A^2/16) of the pendulum.
            omega0 = 2.0 * math.pi / period * (1.0 + amp * amp / 32.0)
            return float(np.clip(replay.nominal["g"] / omega0**2, eff.lower, 10.0))
    return float(nominal)


def fit_model(replay: Replay, causes: tuple[str, ...] = (), starts: dict[str, float] | None = None) -> Fit:
    """Fit the ``causes``' parameters (and nuisance parameters) on the training part.

    ``starts`` gives starting values by parameter name, e.g. the nominal fit's
    nuisance values, so that a candidate starts from the optimum it nests.
    """
    starts = starts or {}
    names: list[str] = []
    start: list[float] = []
    scale: list[float] = []
    lo: list[float] = []
    hi: list[float] = []
    for cause in causes:
        eff = effect(cause)
        s0 = starts.get(eff.param, start_value(replay, eff))
        # trf's scaling freezes a variable that starts on its bound: start just inside.
        s0 = max(s0, eff.lower + 0.05 * eff.scale)
        names.append(eff.param)
        start.append(s0)
        scale.append(max(abs(s0), eff.scale))
        lo.append(eff.lower)
        hi.append(eff.upper)
    if replay.fits_initial_state:
        for nm in NUISANCE:
            names.append(nm)
            start.append(starts.get(nm, replay.initial_guess[nm]))
            scale.append(_NUISANCE_SCALE[nm])
            lo.append(-math.inf)
            hi.append(math.inf)
    start_a, scale_a = np.array(start), np.array(scale)
    lo_u = (np.array(lo) - start_a) / scale_a
    hi_u = (np.array(hi) - start_a) / scale_a

    def values_of(u: np.ndarray) -> dict[str, float]:
        return dict(zip(names, start_a + scale_a * u))

    def residual(u: np.ndarray, stop: int) -> np.ndarray:
        r = replay.residuals(replay.simulate(values_of(u), stop), slice(0, stop))
        return np.where(np.isfinite(r), r, _DIVERGED)

    u = np.zeros(len(names))
    jac = None
    if names:
        # Fit a short prefix first so single shooting starts inside the right basin.
        stages = [replay.n_train // 4, replay.n_train] if replay.kind == "free_decay" else [replay.n_train]
        for stop in stages:
            res = least_squares(
                residual, u, args=(stop,), bounds=(lo_u, hi_u), method="trf", diff_step=1e-5, x_scale=1.0
            )
            u = res.x
        jac = res.jac
    r = residual(u, replay.n_train)
    n, k = r.size, len(names)
    rss = float(r @ r)
    bic = n * math.log(max(rss, 1e-300) / n) + k * math.log(n)
    values = values_of(u)
    stderr = _stderr(jac, r, scale_a, names) if names else {}
    sim = replay.simulate(values)
    return Fit(tuple(causes), values, stderr, replay.nrmse(sim, replay.train), replay.nrmse(sim, replay.held_out), bic, sim)


def _stderr(jac: np.ndarray, r: np.ndarray, scale: np.ndarray, names: list[str]) -> dict[str, float]:
    """Jacobian standard errors, inflated by (1 + rho)/(1 - rho) for residual autocorrelation rho."""
    n, k = jac.shape
    s2 = float(r @ r) / max(n - k, 1)
    rho = float(np.clip(np.corrcoef(r[:-1], r[1:])[0, 1], 0.0, 0.999)) if n > 3 else 0.0
    try:
        cov = np.linalg.pinv(jac.T @ jac) * s2 * (1.0 + rho) / (1.0 - rho)
    except np.linalg.LinAlgError:
        return {nm: math.inf for nm in names}
    return {nm: float(sc * math.sqrt(max(c, 0.0))) for nm, sc, c in zip(names, scale, np.diag(cov))}


@dataclass
class Diagnosis:
    """Nominal comparison, ranked candidates and verdict of one record."""

    replay: Replay
    nominal: Fit
    candidates: list[Fit]
    noise_floor: float
    cause: str
    tests: dict[str, Any]

    @property
    def best(self) -> Fit | None:
        return next((c for c in self.candidates if c.cause == self.cause), None)

    @property
    def error_after(self) -> float:
        return self.best.error_after if self.best else self.nominal.error_after

    def to_json(self) -> dict[str, Any]:
        """The issue's keys: cause, estimate, uncertainty, error_before/after, gain, candidates."""
        best = self.best
        before = self.nominal.error_after
        return {
            "cause": self.cause,
            "estimate": best.estimate if best else {},
            "uncertainty": best.uncertainty if best else {},
            "error_before": before,
            "error_after": self.error_after,
            "gain": 1.0 - self.error_after / before if before > 0 else 0.0,
            "candidates": [
                {"cause": c.cause, "estimate": c.estimate, "error_after": c.error_after, "bic": c.bic}
                for c in self.candidates
            ],
        }


def held_out_test(replay: Replay, before: Fit, after: Fit) -> float:
    """One-sided p value that ``after`` predicts the held-out part better.

    The held-out part is cut into ``BLOCKS`` contiguous blocks; the t test is on
    the blocks' log ratios of mean squared error, which are far less
    heavy-tailed than the differences when the nominal error grows along
    the record.
    """
    part = replay.held_out
    rb = replay.residuals(before.sim, part)
    ra = replay.residuals(after.sim, part)
    mb = np.array([b.mean() for b in np.array_split(rb * rb, BLOCKS)])
    ma = np.array([a.mean() for a in np.array_split(ra * ra, BLOCKS)])
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.log(mb / ma)
    if not np.all(np.isfinite(d)):
        return 1.0
    sd = d.std(ddof=1)
    if sd == 0.0:
        return 0.0 if d.mean() > 0 else 1.0
    return float(stats.t.sf(d.mean() / (sd / math.sqrt(BLOCKS)), BLOCKS - 1))


def diagnose(replay: Replay, causes: list[str] | None = None, n_jobs: int = 1) -> Diagnosis:
    """Fit the nominal model and every applicable candidate; return the verdict.

    Parameters
    ----------
    replay : Replay
    causes : list of str, optional
        Restrict the candidates (default: all applicable to the record's kind).
    n_jobs : int
        Candidates fitted in parallel (threads; the kernels release the GIL).
    """
    allowed = [e.cause for e in applicable(replay.kind)]
    causes = allowed if causes is None else list(causes)
    bad = [c for c in causes if c not in allowed]
    if bad:
        raise ConfigError(
            f"cause(s) {', '.join(bad)} do not apply to kind {replay.kind!r}; applicable: {', '.join(allowed)}"
        )
    nominal = fit_model(replay)
    nuisance = {k: nominal.values[k] for k in NUISANCE} if replay.fits_initial_state else {}
    fits = Parallel(n_jobs=n_jobs, prefer="threads")(delayed(fit_model)(replay, (c,), nuisance) for c in causes)
    floor = replay.noise_floor()
    tests: dict[str, Any] = {"noise_floor": floor}
    verdict = "none"
    best = _best_if_significant(replay, nominal, fits, floor, tests)
    if best is not None:
        verdict = best.cause
    # Greedy second round from the best single cause (named or not: a single
    # effect may fail the consistency test when a second one is present).
    first = min(fits, key=lambda f: (f.error_after, f.bic)) if fits else None
    if first is not None and len(causes) > 1 and first.error_after > SECOND_ROUND_FLOOR * floor:
        starts = dict(nuisance, **first.values)
        pairs = Parallel(n_jobs=n_jobs, prefer="threads")(
            delayed(fit_model)(replay, first.causes + (c,), starts) for c in causes if c != first.cause
        )
        second: dict[str, Any] = {}
        pair = _best_if_significant(replay, first, pairs, floor, second)
        tests["second_round"] = second
        # The pair must also remove most of what the single cause leaves above the floor.
        explained = pair is not None and (
            first.error_after**2 - pair.error_after**2 > SECOND_ROUND_SHARE * (first.error_after**2 - floor**2)
        )
        if explained and _best_if_significant(replay, nominal, [pair], floor, {}) is not None:
            verdict = pair.cause
        fits += pairs
    fits.sort(key=lambda f: (f.error_after, f.bic))
    return Diagnosis(replay, nominal, fits, floor, verdict, tests)


def _best_if_significant(replay: Replay, base: Fit, fits: list[Fit], floor: float, tests: dict[str, Any]) -> Fit | None:
    """The fit with the lowest held-out error if it passes the three tests against ``base``."""
    if not fits:
        return None
    best = min(fits, key=lambda f: (f.error_after, f.bic))
    reduction = base.error_after**2 - best.error_after**2
    p = held_out_test(replay, base, best)
    dbic = base.bic - best.bic
    tests.update(best=best.cause, reduction=reduction, reduction_needed=FLOOR_SHARE * floor**2, p_value=p, delta_bic=dbic)
    if reduction > FLOOR_SHARE * floor**2 and p < P_VALUE and dbic > DELTA_BIC:
        return best
    return None
