"""Diagnosis of a substructured test part by part: transfer system, physical substructure, numerical model.

:func:`diagnose_parts` answers the lab engineer's question when a hybrid test
goes wrong: blame the numerical model, the specimen or the actuator? It

1. identifies the **transfer system** from the command ``y_cmd`` to the
   measured platform displacement ``y`` (:mod:`.transfer`) and compares it
   with the record's nominal actuator at the forcing frequency;
2. replays the **physical substructure** driven by the identified platform
   motion, against the encoder and the load cell (:class:`.parts.PhysicalReplay`);
3. replays the **numerical model** driven by the forces the controller was
   given, against its own output (:class:`.parts.NumericalReplay`; records
   without ``Fe``, such as an experimental site's log, skip this part);

each with the causes that belong to it (:data:`.effects.PART_OF`). A cause
is named for the part whose own replay it explains; the verdict is every
named cause, and the report says which part each belongs to.

Actuator verdicts (step 1), against the nominal actuator (the record's
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

from ...engine.scan import Work
from ...errors import ConfigError
from ..records import DAQ_KEYS, Record
from .effects import ACTUATOR_CAUSES, PART_OF
from .fit import DIAGNOSIS_BYTES_PER_SAMPLE, FIT_EVALUATIONS, Diagnosis, diagnose
from .parts import NumericalReplay, PhysicalReplay, physical_substeps
from .thresholds import BEAM, DERIVATIVE_RATIO, PARTNERS, Z_MIN
from .transfer import Actuator, TransferIdentification, dominant_frequency, identify_transfer, nominal_actuator

#: Largest difference of effective delay at the forcing frequency that is a convention, not a fault [s].
DELAY_TOLERANCE = 1.5e-3
#: Largest difference of static gain that is not a fault [-].
GAIN_TOLERANCE = 0.02
#: Largest relative difference of a second-order servo's natural frequency that is not a fault [-].
BANDWIDTH_TOLERANCE = 0.2
#: The load cell may read this many times more or less than the nominal specimen's force before the
#: record is refused as a unit error: a gain error of the load cell is a few to tens of per cent, a unit
#: error a factor of 1000 (kN, mN); the margin leaves room for a load cell whose noise swamps a small motion.
FORCE_SCALE_LIMITS = (0.05, 20.0)
#: Channels a record needs for each part.
PART_CHANNELS = {"transfer": ("y_cmd", "y"), "physical": ("theta", "Fs"), "numerical": ("Fe",)}


def forcing_frequency(record: Record) -> float:
    """The frequency the actuator is judged at [Hz]: the record's forcing ``fe``, else the command's main tone."""
    if "fe" in record.forcing:
        return float(record.forcing["fe"])
    return dominant_frequency(record.channel("y_cmd"), record.dt)


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


#: Model evaluations of one transfer identification, an upper estimate: 3 models x (2 held-out
#: fits + 1 full fit) x up to 3 starts x about 40 evaluations.
TRANSFER_EVALUATIONS = 3 * 3 * 3 * 40


def parts_work(records: list[Record], causes: list[str] | None = None) -> Work:
    """An upper estimate of :func:`diagnose_parts`' work (:func:`pendsweep.engine.scan.check_work`).

    ``units`` counts whole-record evaluations: the transfer fits, and the two
    part replays' fits (:data:`.fit.FIT_EVALUATIONS` each, for the nominal,
    every candidate and the second round); ``steps`` is the integration steps
    of one evaluation of every record (the servo and pendulum substeps).
    """
    n_physical = len([c for c in PART_OF.values() if c == "physical"]) + len(_PHYSICAL_CHAIN)
    n_numerical = len([c for c in PART_OF.values() if c == "numerical"])
    fits = sum(1 + k + BEAM * PARTNERS for k in (n_physical, n_numerical))
    steps = float(sum(len(r.data) * 2 * physical_substeps(r.dt) for r in records))
    samples = sum(len(r.data) for r in records)
    return Work(
        TRANSFER_EVALUATIONS + fits * FIT_EVALUATIONS, 1.0, steps, result_bytes=2 * samples * DIAGNOSIS_BYTES_PER_SAMPLE
    )


def has_parts(record: Record) -> bool:
    """Whether ``record`` holds what the part-by-part diagnosis needs (command, motion, angle, load cell)."""
    return all(c in record.data for c in PART_CHANNELS["transfer"] + PART_CHANNELS["physical"])


def diagnose_parts(
    records: list[Record],
    causes: list[str] | None = None,
    n_jobs: int = 1,
    horizon: float | None = None,
    folds: int = 5,
) -> PartsDiagnosis:
    """Diagnose substructured (or site-log) records part by part (module docstring).

    Parameters
    ----------
    records : list of Record
        Records of one rig, each with ``y_cmd``, ``y``, ``theta`` and ``Fs``
        (``Fe`` too for the numerical part).
    causes : list of str, optional
        Restrict the candidates; each goes to its part (:data:`.effects.PART_OF`).
    n_jobs : int
        Candidates fitted in parallel.
    horizon : float, optional
        Segment length of the part replays [s].
    folds : int
        Cross-validation folds.
    """
    for r in records:
        missing = [c for c in PART_CHANNELS["transfer"] + PART_CHANNELS["physical"] if c not in r.data]
        if missing:
            raise ConfigError(f"{r.name}: a part-by-part diagnosis needs column(s) {', '.join(missing)}")
    wanted = None if causes is None else set(causes)
    unknown = sorted((wanted or set()) - set(PART_OF))
    if unknown:
        raise ConfigError(f"cause(s) {', '.join(unknown)} do not apply to a substructured test's parts; "
                          f"applicable: {', '.join(sorted(PART_OF))}")  # fmt: skip
    transfers, verdicts, physical = [], [], []
    for r in records:
        ident = identify_transfer(
            r.t,
            r.channel("y_cmd"),
            r.channel("y"),
            forcing_frequency(r),
            nominal_actuator(r.actuator, r.tau),
            r.sampling("command"),
        )
        verdict = judge_transfer(ident)
        verdict["measured_derivatives"] = ident.compare_derivatives(
            {c: r.channel(c) for c in ("ydot", "yddot") if c in r.data}
        )
        if wanted is not None:
            verdict["causes"] = [c for c in verdict["causes"] if c in wanted]
            verdict["estimates"] = {c: v for c, v in verdict["estimates"].items() if c in wanted}
        transfers.append(ident)
        verdicts.append(verdict)
        substeps = physical_substeps(r.dt)
        fit = ident.motion_fit
        motion = ident.problem.motion(fit.actuator, 2 * substeps, fit.initial)
        physical.append(PhysicalReplay(r, motion, substeps, horizon, folds))
        _check_force_scale(physical[-1], r)

    def restricted(part: str) -> list[str] | None:
        if wanted is None:
            return None
        return [c for c in sorted(wanted) if PART_OF[c] == part or (part == "physical" and c in _PHYSICAL_CHAIN)]

    skipped: dict[str, str] = {}
    physical_causes = restricted("physical")
    physical_diag = None
    if physical_causes == []:
        skipped["physical"] = "--cause named none of its causes"
    else:
        physical_diag = diagnose(physical, physical_causes, n_jobs)
    numerical_causes = restricted("numerical")
    numerical_diag = None
    if not all("Fe" in r.data for r in records):
        skipped["numerical"] = "the record has no Fe, the numerical model's input (an experimental site's log)"
    elif numerical_causes == []:
        skipped["numerical"] = "--cause named none of its causes"
    else:
        numerical_diag = diagnose([NumericalReplay(r, horizon, folds) for r in records], numerical_causes, n_jobs)
    return PartsDiagnosis(transfers, verdicts, physical_diag, numerical_diag, skipped)


def _check_force_scale(replay: PhysicalReplay, record: Record) -> None:
    """Refuse a load cell whose spread is far from the nominal specimen's force: kN read as N, or the reverse."""
    modelled = replay.simulate({})["Fs"]
    measured = record.channel("Fs")
    valid = np.isfinite(modelled)
    ratio = float(np.std(measured[valid]) / np.std(modelled[valid])) if valid.any() else 1.0
    low, high = FORCE_SCALE_LIMITS
    if not low <= ratio <= high:
        declared = {k: v for k in ("load_cell", "command") if (v := record.sampling(k)) != DAQ_KEYS[k][0]}
        hint = ""
        if declared and not record.actuator:
            hint = (
                f"; or: the record declares daq {declared}, whose replay needs the servo described in the "
                "metadata's actuator table"
            )
        raise ConfigError(
            f"{record.name}: the load cell Fs reads {ratio:.3g} x the force the nominal specimen gives on this "
            'motion: check its units (declare them in the metadata\'s columns, e.g. {"Fs": {"unit": "kN"}})' + hint
        )


#: Sensor causes of the transfer system that the physical replay fits (the load cell's gain, the encoder's zero).
_PHYSICAL_CHAIN = tuple(c for c, part in PART_OF.items() if part == "transfer" and c not in ACTUATOR_CAUSES)


def diagnose_records(
    records: list[Record],
    causes: list[str] | None = None,
    n_jobs: int = 1,
    horizon: float | None = None,
    folds: int = 5,
    method: str = "parts",
) -> Diagnosis | PartsDiagnosis:
    """The diagnosis of records of one rig: part by part (``method="parts"``) for substructured records
    and site logs that hold the channels (:func:`has_parts`), else the whole-record replay's."""
    from .replay import Replay

    if _by_parts(records, method):
        return diagnose_parts(records, causes, n_jobs, horizon, folds)
    return diagnose([Replay(r, horizon, folds) for r in records], causes, n_jobs)


def diagnosis_work_of(records: list[Record], causes: list[str] | None = None, method: str = "parts") -> Work:
    """The work estimate of :func:`diagnose_records` with the same arguments."""
    from .fit import diagnosis_work
    from .replay import Replay

    if _by_parts(records, method):
        return parts_work(records, causes)
    return diagnosis_work([Replay(r) for r in records], causes)


def _by_parts(records: list[Record], method: str) -> bool:
    """Whether ``records`` are diagnosed part by part; a rig record (a site log) must be."""
    if method not in ("parts", "closed-loop"):
        raise ConfigError(f"method {method!r}; choose parts or closed-loop")
    kinds = {r.kind for r in records}
    if method == "parts" and kinds <= {"substructured", "rig"}:
        if all(has_parts(r) for r in records):
            return True
        lacking = next(r for r in records if not has_parts(r))
        missing = [c for c in PART_CHANNELS["transfer"] + PART_CHANNELS["physical"] if c not in lacking.data]
        raise ConfigError(
            f"{lacking.name}: no {', '.join(missing)} column: a part-by-part diagnosis needs the load cell and the "
            "encoder; pass --method closed-loop to replay the whole loop instead"
        )
    if "rig" in kinds:
        raise ConfigError(f"{records[0].name}: a rig record (a site log) is diagnosed part by part only")
    return False
