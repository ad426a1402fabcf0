"""The judge stage's verdict on one replayed part: :class:`Diagnosis` (the :mod:`.tests` of the fit stage's
best single cause and best pair, what remains, ties and stated uncertainties).

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

from ..fit import Fit, Problem, channel_ratios, structured_residual
from ..identify.oscillator import OscillatorIdentification
from ..replay import Replay
from ..signatures import residual_signature
from .tests import (
    P_VALUE,
    SHARE_MIN,
    UNCERTAINTY_CALIBRATION,
    UNEXPLAINED_RATIO,
    _quantisation_bounded,
    block_test,
    failed_tests,
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
    #: Per record, the oscillator's dynamics read off it before any replay (:mod:`..identify.oscillator`), or None.
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
        """Why each tied look-alike of the verdict is tied, from what the record holds (:mod:`..identify.oscillator`).

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
