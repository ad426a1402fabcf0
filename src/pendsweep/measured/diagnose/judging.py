"""The tests a fitted candidate must pass to be named: scores, held-out block tests, z, channel ratios, plausibility."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import stats

from .effects import effect
from .fitting import EXACT_CHANNELS, Fit, Problem, _resting_level_sigma
from .thresholds import CHANNEL_RATIO, FLOOR_SHARE, IMPLAUSIBLE_FACTOR, P_VALUE, RELEVANCE, Z_BOUNDED, Z_MIN


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
        r0.append(rp.fit_residuals(rp.simulate(problem.record_values(base, i)), rp.eval_idx))
        r1.append(rp.fit_residuals(rp.simulate(problem.record_values(moved, i)), rp.eval_idx))
    r0, r1 = np.concatenate(r0), np.concatenate(r1)
    j = r1 - r0
    if not (np.all(np.isfinite(j)) and np.all(np.isfinite(r0))) or j @ j == 0:
        return 0.0
    return float((j @ r0) ** 2 / (j @ j))


def _rank(fit: Fit) -> tuple[float, float, str]:
    """Ranking key of candidates: cross-validated error, then BIC, then the name (deterministic ties)."""
    return fit.error_cv, fit.bic, fit.cause or ""


def block_test(before: Fit, after: Fit, whitened: bool = False) -> float:
    """One-sided p value that ``after`` predicts the held-out blocks better than ``before``.

    Wilcoxon signed-rank test on the blocks' differences of out-of-fold mean
    squared error (``whitened``: in units of each channel's noise, see
    :func:`.fitting._whitened_square`); zero differences (e.g. blocks where
    both models are exact) are split between the signs instead of being
    dropped or breaking the test.
    """
    b, a = (before.block_chi2, after.block_chi2) if whitened else (before.block_mse, after.block_mse)
    if b is None or a is None or np.all(np.isnan(b)):
        return 1.0
    fb, fa = np.isfinite(b), np.isfinite(a)
    with np.errstate(invalid="ignore"):
        d = b - a
    if not np.all(fb & fa):
        # A model that diverges on a block is the worse one there (largest rank); both diverging: a tie.
        big = 2.0 * float(np.max(np.abs(d[fb & fa]), initial=1.0))
        d = np.where(fb & fa, d, np.where(fa, big, np.where(fb, -big, 0.0)))
    if np.all(d == 0.0):
        return 1.0
    return float(stats.wilcoxon(d, zero_method="zsplit", alternative="greater").pvalue)


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
    relevant = {c: _relevant_change(problem, model, c) for c in causes}
    passed = (
        share >= share_min
        and reduction > FLOOR_SHARE * floor2
        and p < P_VALUE
        and all(z >= needed[c] and stable for c, (z, stable) in zs.items())
        and all(ok for ok, _, _ in relevant.values())
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
        "relevant": {c: {"change": change, "needed": need} for c, (_, change, need) in relevant.items() if need},
        "passed": bool(passed),
    }


def _relevant_change(problem: Problem, fit: Fit, cause: str) -> tuple[bool, float, float]:
    """Whether ``cause``'s relative change from nominal reaches :data:`RELEVANCE` (its kind's, else none);
    the smallest change over its parameters and the change needed."""
    param = effect(cause).param
    need = RELEVANCE.get(problem.kind, {}).get(param, 0.0)
    changes = [abs(fit.values[k] / problem.nominal_of(k) - 1.0) for k in fit.keys_of(cause) if problem.nominal_of(k)]
    change = min(changes, default=math.inf)
    return change >= need, change, need


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
    for c, r in j.get("relevant", {}).items():
        if r["change"] < r["needed"]:
            out.append(f"{c}: changes {100 * r['change']:.1f} % from nominal, {100 * r['needed']:g} % is a fault")
    if j.get("chain_ok") is False:
        out.append("does not beat its single cause with the actuator delay freed (absorbs model-form error)")
    return out
