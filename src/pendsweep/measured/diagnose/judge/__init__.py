"""The diagnosis's fourth stage, judge: the tests of the fit stage's candidates, and the verdict.

:func:`judge` takes the fit stage's :class:`~..fit.Fits` of one replayed part
and returns its :class:`Diagnosis`: the best plausible single cause is tested
against the nominal model, the best pair (when the fit stage ran a second
round) against its better single cause and against the nominal, and the
verdict names the candidate that passes (:mod:`.verdict`; the tests and their
thresholds: :mod:`.tests`). :func:`judge_parts` adds the transfer system's
verdict of a substructured test (:mod:`.parts`) to its parts' diagnoses.
"""

from __future__ import annotations

from typing import Any

from ..fit import Fits
from ..identify import Transfers
from .parts import BANDWIDTH_TOLERANCE, DELAY_TOLERANCE, GAIN_TOLERANCE, PartsDiagnosis, judge_transfer
from .tests import SECOND_SHARE_MIN, SHARE_MIN, _judge, block_test, failed_tests
from .verdict import FORCED_TIES, Diagnosis

__all__ = [
    "BANDWIDTH_TOLERANCE",
    "DELAY_TOLERANCE",
    "FORCED_TIES",
    "GAIN_TOLERANCE",
    "Diagnosis",
    "PartsDiagnosis",
    "block_test",
    "failed_tests",
    "judge",
    "judge_parts",
    "judge_transfer",
]


def judge(fits: Fits) -> Diagnosis:
    """The verdict on one part's fits (:mod:`.verdict`): first round, second round, what is named."""
    problem, nominal, first = fits.problem, fits.nominal, fits.first
    tests: dict[str, Any] = {"noise_floor": problem.floor, "implausible": fits.implausible}
    verdict = "none"
    if first is not None:
        tests["first_round"] = _judge(problem, nominal, first, SHARE_MIN, first.causes)
        if tests["first_round"]["passed"]:
            verdict = first.cause
    if fits.pair is not None:
        pair, base = fits.pair, fits.base
        tests["partner_scores"] = fits.partner_scores
        second = _judge(problem, base, pair, SECOND_SHARE_MIN, pair.causes)
        against_nominal = _judge(problem, nominal, pair, SHARE_MIN, pair.causes)
        second["against_nominal_passed"] = against_nominal["passed"]
        tests["second_against_nominal"] = against_nominal
        chain_ok = True
        if fits.with_delay is not None:
            # The pair must beat its single cause with the actuator's delay freed:
            # otherwise the second parameter is soaking up the actuator's model-form error.
            chained = fits.with_delay
            second["chain_check"] = {"single_with_delay_error": chained.error_cv, "pair_error": pair.error_cv}
            chain_ok = pair.error_cv**2 < chained.error_cv**2 - 0.5 * (base.error_cv**2 - pair.error_cv**2)
        second["chain_ok"] = chain_ok
        tests["second_round"] = second
        if second["passed"] and against_nominal["passed"] and chain_ok and pair.cause not in tests["implausible"]:
            verdict = pair.cause
    return Diagnosis(problem, nominal, fits.candidates, verdict, tests, fits.identified)


def judge_parts(
    transfers: Transfers,
    physical: Fits | None,
    numerical: Fits | None,
    skipped: dict[str, str],
    wanted: set[str] | None = None,
) -> PartsDiagnosis:
    """The verdict of a substructured test part by part: each record's transfer system (only the causes in
    ``wanted``, when given), and the physical and numerical parts' fits (None: not replayed, ``skipped`` says why)."""
    verdicts = []
    for ident, derivatives in zip(transfers.transfers, transfers.derivatives):
        verdict = judge_transfer(ident)
        verdict["measured_derivatives"] = derivatives
        if wanted is not None:
            verdict["causes"] = [c for c in verdict["causes"] if c in wanted]
            verdict["estimates"] = {c: v for c, v in verdict["estimates"].items() if c in wanted}
        verdicts.append(verdict)
    physical_diag = None if physical is None else judge(physical)
    numerical_diag = None if numerical is None else judge(numerical)
    return PartsDiagnosis(transfers.transfers, verdicts, physical_diag, numerical_diag, skipped)
