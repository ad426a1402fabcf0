"""The judge stage's verdict on a substructured test part by part: the transfer system's, and
:class:`PartsDiagnosis` (the transfer system, the physical part's and the numerical part's verdicts).

Actuator verdicts (of the identify stage's transfer system), against the nominal actuator (the record's
``actuator`` metadata, else a pure delay of its ``tau``):

``actuator_delay``
    the selected model's effective delay at the forcing frequency differs
    from the nominal's by more than :data:`DELAY_TOLERANCE` and by more than
    ``Z_MIN`` of its uncertainty;
``servo_bandwidth``
    instead of ``actuator_delay``, when the nominal actuator is a servo, a
    servo of its order is selected, its transport delay agrees with the
    nominal's (within the same tolerances) and its rate does not (by
    :data:`BANDWIDTH_TOLERANCE` and ``Z_MIN``); where the selected model does
    not separate the two (a simpler model, or both or neither off), the
    verdict is ``actuator_delay`` tied with ``servo_bandwidth``, whose
    estimate is :func:`bandwidth_for_delay`;
``servo_gain``
    the static gain differs from the nominal's by more than
    :data:`GAIN_TOLERANCE` and ``Z_MIN`` of its uncertainty.

The tolerances are the convention differences between labs that are not
faults: a command held instead of ramped over a tick adds half a tick of
delay (1 ms at 500 Hz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import brentq

from ..effects import PART_OF
from ..identify.transfer import Actuator, TransferIdentification
from .tests import DERIVATIVE_RATIO, Z_MIN
from .verdict import Diagnosis

#: Largest difference of effective delay at the forcing frequency that is a convention, not a fault [s].
DELAY_TOLERANCE = 1.5e-3
#: Largest difference of static gain that is not a fault [-].
GAIN_TOLERANCE = 0.02
#: Largest relative difference of a second-order servo's natural frequency that is not a fault [-].
BANDWIDTH_TOLERANCE = 0.2


def judge_transfer(ident: TransferIdentification) -> dict[str, Any]:
    """The actuator causes the identification supports (module docstring), with estimates and tests."""
    best, nominal, f = ident.best, ident.nominal, ident.frequency
    delay, delay_sigma = best.effective_delay(f)
    nominal_delay = nominal.effective_delay(f)
    gain, gain_sigma = best.actuator.gain, best.stderr["gain"]

    def differs(change: float, sigma: float, tolerance: float) -> bool:
        return abs(change) > tolerance and abs(change) > Z_MIN * sigma

    tests: dict[str, Any] = {
        "effective_delay": {"estimate": delay, "nominal": nominal_delay, "uncertainty": delay_sigma,
                            "tolerance": DELAY_TOLERANCE, "differs": differs(delay - nominal_delay, delay_sigma, DELAY_TOLERANCE)},
        "gain": {"estimate": gain, "nominal": nominal.gain, "uncertainty": gain_sigma, "tolerance": GAIN_TOLERANCE,
                 "differs": differs(gain - nominal.gain, gain_sigma, GAIN_TOLERANCE)},
    }  # fmt: skip
    named: dict[str, tuple[str, float, float]] = {}
    tied: dict[str, tuple[str, float]] = {}
    if tests["effective_delay"]["differs"]:
        named["actuator_delay"] = ("tau", delay, delay_sigma)
        # Whether the selected model tells a longer transport delay from a slower servo: only a
        # servo of the nominal's order, with one of the two as nominal, does.
        separated = False
        if nominal.order >= 1 and best.actuator.order == nominal.order:
            rate, rate_sigma = best.actuator.rate, best.stderr["rate"]
            transport_same = not differs(best.actuator.tau - nominal.tau, best.stderr["tau"], DELAY_TOLERANCE)
            rate_differs = differs((rate - nominal.rate) / nominal.rate, rate_sigma / nominal.rate, BANDWIDTH_TOLERANCE)
            tests["bandwidth"] = {"estimate": rate, "nominal": nominal.rate, "uncertainty": rate_sigma,
                                  "tolerance": BANDWIDTH_TOLERANCE, "transport_delay_as_nominal": transport_same,
                                  "differs": rate_differs}  # fmt: skip
            separated = transport_same == rate_differs
            if transport_same and rate_differs:
                del named["actuator_delay"]
                named["servo_bandwidth"] = ("rate", rate, rate_sigma)
        if nominal.order >= 1 and not separated:
            # The record holds too little above the forcing to say which changed: a tie, with the
            # nominal servo's rate that gives the same effective delay as the alternative.
            rate = bandwidth_for_delay(nominal, f, delay)
            if rate is not None:
                tied["servo_bandwidth"] = ("rate", rate)
    if tests["gain"]["differs"]:
        named["servo_gain"] = ("gain_servo", gain, gain_sigma)
    return {"causes": sorted(named), "estimates": named, "tied_with": tied, "tests": tests}


def bandwidth_for_delay(nominal: Actuator, f: float, delay: float) -> float | None:
    """The rate of the nominal servo (its transport delay kept) whose effective delay at ``f`` is ``delay``.

    The alternative explanation of a longer effective delay; None when no slower servo of the
    nominal's order reaches it (its phase lag is bounded: 90 deg for the first order, 180 for the second).
    """

    w = 2.0 * math.pi * f

    def excess(log_rate: float) -> float:
        # The servo's phase lag on its continuous branch (no wrapping): 0 to 90 or 180 deg.
        rate = math.exp(log_rate)
        lag = math.atan2(w, rate) if nominal.order == 1 else math.atan2(2.0 * nominal.zeta * rate * w, rate**2 - w**2)
        return nominal.tau + lag / w - delay

    low, high = math.log(w * 1e-3), math.log(max(nominal.rate, w) * 1e3)
    if not excess(low) > 0.0 > excess(high):
        return None
    return math.exp(brentq(excess, low, high, xtol=1e-10))


@dataclass
class PartsDiagnosis:
    """The verdict of a substructured record, part by part (module docstring).

    Attributes
    ----------
    transfers : list of TransferIdentification
        One per record.
    transfer_verdicts : list of dict
        :func:`judge_transfer` of each.
    physical, numerical : Diagnosis or None
        The part replays' diagnoses; None for a part that was not replayed
        (``--cause`` named none of its causes; no ``Fe`` in the records for
        the numerical part, as in an experimental site's log).
    skipped : dict
        Why each part that was not replayed was not.
    """

    transfers: list[TransferIdentification]
    transfer_verdicts: list[dict[str, Any]]
    physical: Diagnosis | None
    numerical: Diagnosis | None
    skipped: dict[str, str]

    @property
    def causes(self) -> list[str]:
        named = {c for v in self.transfer_verdicts for c in v["causes"]}
        for d in self.diagnoses:
            if d.cause != "none":
                named.update(d.cause.split("+"))
        return sorted(named)

    @property
    def cause(self) -> str:
        return "+".join(self.causes) or "none"

    @property
    def diagnoses(self) -> list[Diagnosis]:
        return [d for d in (self.physical, self.numerical) if d is not None]

    @property
    def unexplained(self) -> bool:
        """A part's replay leaves more than noise, or a measured platform velocity or acceleration
        disagrees with the motion that drove the specimen's replay (:data:`DERIVATIVE_RATIO`)."""
        return any(d.unexplained for d in self.diagnoses) or bool(self.motion_mismatch())

    def motion_mismatch(self) -> list[str]:
        """The measured platform derivatives (``ydot``, ``yddot``) the identified motion misses by more than
        :data:`DERIVATIVE_RATIO` times their noise variance, as ``column@record``."""
        return [
            f"{column}@{i}"
            for i, verdict in enumerate(self.transfer_verdicts)
            for column, check in verdict.get("measured_derivatives", {}).items()
            if check["ratio_to_noise"] > DERIVATIVE_RATIO
        ]

    def _pooled(self, error) -> float:
        """Sample-weighted RMS over the replayed parts of a per-part NRMSE, ``error(diagnosis)``."""
        weights = [sum(len(rp.eval_idx) * len(rp.channels) for rp in d.problem.replays) for d in self.diagnoses]
        squares = [error(d) ** 2 for d in self.diagnoses]
        return float(math.sqrt(np.average(squares, weights=weights))) if weights else 0.0

    def to_json(self) -> dict[str, Any]:
        parts: dict[str, Any] = {}
        estimate: dict[str, float] = {}
        uncertainty: dict[str, float] = {}
        transfer = []
        for ident, verdict in zip(self.transfers, self.transfer_verdicts):
            entry = ident.to_json()
            entry.update(
                cause="+".join(verdict["causes"]) or "none",
                tests=verdict["tests"],
                measured_derivatives=verdict.get("measured_derivatives", {}),
            )
            transfer.append(entry)
            for name, value, sigma in verdict["estimates"].values():
                key = name if len(self.transfers) == 1 else f"{name}@{len(transfer) - 1}"
                estimate[key], uncertainty[key] = value, sigma
            entry["tied_with"] = {cause: {name: value} for cause, (name, value) in verdict["tied_with"].items()}
        parts["transfer"] = transfer[0] if len(transfer) == 1 else transfer
        tied: list[str] = [c for v in self.transfer_verdicts for c in v["tied_with"]]
        for name, d in (("physical", self.physical), ("numerical", self.numerical)):
            if d is None:
                parts[name] = {"cause": "not replayed", "reason": self.skipped[name]}
                continue
            js = d.to_json()
            parts[name] = js
            estimate.update(js["estimate"])
            uncertainty.update(js["uncertainty"])
            tied += js["tied_with"]
        before = self._pooled(lambda d: d.nominal.error_cv)
        after = self._pooled(lambda d: d.error_after)
        floor = self._pooled(lambda d: d.noise_floor)
        excess = before**2 - floor**2
        return {
            "cause": self.cause,
            "method": "parts",
            "part_of": {c: PART_OF[c] for c in self.causes},
            "estimate": estimate,
            "uncertainty": uncertainty,
            "error_before": before,
            "error_after": after,
            "gain": 1.0 - after / before if self.cause != "none" and before > 0 else 0.0,
            "explained_share": float(np.clip((before**2 - after**2) / excess, 0.0, 1.0)) if excess > 0 else 0.0,
            "unexplained": self.unexplained,
            "motion_mismatch": self.motion_mismatch(),
            "tied_with": sorted(set(tied)),
            "noise_floor": floor,
            "parts": parts,
        }
