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
:mod:`pendsweep.measured.diagnose.testbench` only (``docs/measured-data.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from joblib import Parallel, delayed
from threadpoolctl import threadpool_limits

from ...engine.scan import Work
from ...errors import ConfigError
from .effects import EFFECTS, applicable
from .fitting import Fit, Problem, _params, _solve, fit_model
from .identify import OscillatorIdentification, identified_starts
from .judging import (
    _judge,
    _quantisation_bounded,
    _rank,
    _score,
    block_test,
    channel_ratios,
    failed_tests,
    implausible,
    structured_residual,
)
from .replay import Replay
from .thresholds import (
    BEAM,
    P_VALUE,
    PARTNERS,
    SECOND_ROUND_RATIO,
    SECOND_SHARE_MIN,
    SHARE_MIN,
    UNCERTAINTY_CALIBRATION,
    UNEXPLAINED_RATIO,
)

#: Look-alike pairs tied whenever the record cannot separate them (:meth:`Diagnosis.tied_with`). Stiffness
#: against hardening is not: on one steady tone a cubic spring still adds harmonics the replays see.
FORCED_TIES = {frozenset({"oscillator_stiffness", "oscillator_mass"})}


@dataclass
class Diagnosis:
    """Nominal comparison, ranked candidates, verdict and what remains, for one or several records."""

    problem: Problem
    nominal: Fit
    candidates: list[Fit]
    cause: str
    tests: dict[str, Any]
    #: Per record, the oscillator's dynamics read off it before any replay (:mod:`.identify`), or None.
    identified: list[OscillatorIdentification | None] = field(default_factory=list)

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
        held-out blocks (one-sided signed-rank test, p >= :data:`P_VALUE`), neither in the pooled
        error nor in units of each channel's noise: the data do not tell them apart, whatever the
        ranking by cross-validated error says. The second test is what separates look-alikes whose
        difference lies in a channel the pooled error underweights (a small pendulum's angle, a
        few encoder steps, swamps the pooled error with its own noise while the oscillator's
        displacement, many times its noise apart between a stiffness and a hardening, is diluted).
        A look-alike the record cannot separate from the verdict (:meth:`_inseparable`) is tied
        whatever the blocks say.
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
            if share < SHARE_MIN:
                continue
            if self._inseparable(best, c) or (
                block_test(c, best) >= P_VALUE and block_test(c, best, whitened=True) >= P_VALUE
            ):
                out.append(c.cause)
        return out

    def _inseparable(self, best: Fit, other: Fit) -> bool:
        """Whether ``other`` differs from ``best`` by one look-alike of :data:`FORCED_TIES` that every
        record's identification says it cannot separate (one tone in steady state: only ``K - M omega^2``).
        Such a pair is tied whatever the held-out blocks say: their difference there is the sensors' drift
        and noise, not the oscillator (a lighter mass was named as a stiffer spring, and a stiffer spring
        as a lighter mass with the cross-validated errors 0.0014442 against 0.0014445)."""
        found = [i for i in self.identified if i is not None]
        own, theirs = set(best.causes) - set(other.causes), set(other.causes) - set(best.causes)
        if not found or len(own) != 1 or len(theirs) != 1 or frozenset(own | theirs) not in FORCED_TIES:
            return False
        verdicts = [i.separates(next(iter(own)), next(iter(theirs))) for i in found]
        return all(v is not None and not v[0] for v in verdicts)

    def tie_reasons(self) -> dict[str, str]:
        """Why each tied look-alike of the verdict is tied, from what the record holds (:mod:`.identify`).

        For the oscillator's look-alikes (K against M, K against k3): that the record cannot separate
        them (one steady tone: only ``K - M omega^2``; a constant amplitude: a cubic spring is a
        constant stiffness), or that it could in principle and the fits did not.
        """
        best = self.best
        found = [i for i in self.identified if i is not None]
        if best is None or not found:
            return {}
        out = {}
        for tied in self.tied_with():
            for own, other in ((a, b) for a in best.causes for b in tied.split("+") if a != b):
                verdicts = [i.separates(own, other) for i in found]
                if any(v is None for v in verdicts):
                    continue
                if all(not separable for separable, _ in verdicts):
                    out[tied] = f"the record cannot separate {own} from {other}: " + verdicts[0][1]
                else:
                    out[tied] = (
                        f"the record can separate {own} from {other} in principle ({verdicts[0][1]}), "
                        "but the replays' fits do not on the held-out blocks"
                    )
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
            "tie_reasons": self.tie_reasons(),
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
            "identification": [i.to_json() if i is not None else None for i in self.identified],
            "nuisance": {k: v for k, v in self.verdict_fit.values.items() if k.split("@")[0] in self.problem.nuisance},
        }


#: Replays (model evaluations over a whole record) one least-squares fit takes, an upper
#: estimate: measured 17 to 75 on 10,000-sample records of each kind, Jacobians included.
FIT_EVALUATIONS = 100
#: Memory per record sample of a diagnosis [bytes]: every fit keeps its simulated channels
#: (about 20 fits x 5 channels x 8 bytes) besides the record and its smoothed derivatives.
DIAGNOSIS_BYTES_PER_SAMPLE = 1024


def diagnosis_work(replays: list[Replay], causes: list[str] | None = None) -> Work:
    """An upper estimate of a diagnosis's work, before it starts (:func:`pendsweep.engine.scan.check_work`).

    ``units`` is the replays of the whole record set (the nominal fit, one fit
    per candidate and the second round's ``BEAM x PARTNERS`` pairs, each of
    :data:`FIT_EVALUATIONS` replays; several records: times ``1 + 2 n`` for the
    leave-one-record-out refits); ``steps`` the integration steps of one
    replay of every record (samples x substeps). Measured rate: about 80 ns a
    step, so the default limit of 1e10 steps is about a quarter of an hour.
    """
    kinds = {rp.kind for rp in replays}
    n_causes = len(causes) if causes else max(len(applicable(k)) for k in kinds)
    fits = 1 + n_causes + (BEAM * PARTNERS if n_causes > 1 else 0)
    if len(replays) > 1:
        # Leave-one-record-out: every fit is refitted per record, the shared parameters on the others
        # and the record's own on itself (measured 3.3 x on two records).
        fits *= 1 + 2 * len(replays)
    steps = float(sum(rp.n * rp.substeps for rp in replays))
    samples = sum(rp.n for rp in replays)
    return Work(fits * FIT_EVALUATIONS, 1.0, steps, result_bytes=samples * DIAGNOSIS_BYTES_PER_SAMPLE)


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
    nuisance = {k: v for k, v in initial.items() if k.split("@")[0] in problem.replays[0].nuisance}
    # Fitted initial states of a wrong model can be nonsense (a free decay whose period is 3 % off
    # drifts a cycle over 45 swings, and the nominal fit then settles on a swing of 0.02 rad where
    # the data start at 0.5): candidates also start from the data's own initial states, and the
    # better fit is kept.
    data_start = ({},) if any(rp.fits_initial_state for rp in problem.replays) else ()
    # The oscillator's parameters also start where the record points (identify.py): a fit from the
    # nominal can stop in another basin when a resonance lies between the nominal and the truth.
    identified = [rp.identification() for rp in problem.replays]
    pool = Parallel(n_jobs=n_jobs, prefer="threads")
    fits = pool(
        delayed(fit_model)(
            problem,
            (c,),
            nuisance,
            data_start + tuple(dict(nuisance, **s) for s in identified_starts(identified, (c,))),
        )
        for c in causes
    )
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
                start := _without_zeros(dict(nuisance, **s.values)),
                _pair_starts(problem, s, singles[c])
                + tuple(dict(start, **i) for i in identified_starts(identified, s.causes + (c,))),
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
    return Diagnosis(problem, nominal, fits, verdict, tests, identified)
