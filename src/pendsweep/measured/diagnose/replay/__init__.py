"""The diagnosis's second stage, replay: a record's model simulated driven by its recorded inputs.

* :class:`Replay` (:mod:`.whole`): the whole record's model (a free decay, a
  forced oscillator, the substructuring loop), and what is compared of it.
* :class:`PhysicalReplay`, :class:`NumericalReplay` (:mod:`.parts`): the parts
  of a substructured test, each on its own; the physical part driven by the
  motion the identify stage's transfer system gives (:func:`replay_parts`).

The stage's result, :class:`Replayed`, holds the replays and, per replay, the
oscillator's identification it read off its record (the identify stage's
:mod:`..identify.oscillator`, computed once per replay): what the fit stage
starts its candidates from and the judge stage's ties consult.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....errors import ConfigError
from ...records import DAQ_KEYS, Record
from ..identify import OscillatorIdentification, Transfers
from .parts import NumericalReplay, PhysicalReplay, physical_substeps
from .whole import REST_LEVEL_SIGMA, Replay

__all__ = [
    "REST_LEVEL_SIGMA",
    "NumericalReplay",
    "PartReplays",
    "PhysicalReplay",
    "Replay",
    "Replayed",
    "physical_substeps",
    "prepared",
    "replay_parts",
]

#: The load cell may read this many times more or less than the nominal specimen's force before the
#: record is refused as a unit error: a gain error of the load cell is a few to tens of per cent, a unit
#: error a factor of 1000 (kN, mN); the margin leaves room for a load cell whose noise swamps a small motion.
FORCE_SCALE_LIMITS = (0.05, 20.0)


@dataclass
class Replayed:
    """The replay stage's result: replays of one part (in the order given) and each one's oscillator identification."""

    replays: list[Replay]
    identified: list[OscillatorIdentification | None]


@dataclass
class PartReplays:
    """The replay stage's result for a part-by-part diagnosis: the physical part's and (None when it
    is not replayed) the numerical part's replays."""

    physical: Replayed
    numerical: Replayed | None


def prepared(replays: Replay | list[Replay]) -> Replayed:
    """Replays made by the caller, with each one's oscillator identification (None for kinds without one)."""
    replays = replays if isinstance(replays, list) else [replays]
    return Replayed(replays, [rp.identification() for rp in replays])


def replay_parts(
    transfers: Transfers, horizon: float | None = None, folds: int = 5, numerical: bool = True
) -> PartReplays:
    """The physical part of each record driven by its identified platform motion (its load cell's units
    checked against the nominal specimen), and the numerical part driven by its forces (``numerical``)."""
    physical = []
    for r, ident in zip(transfers.records, transfers.transfers):
        substeps = physical_substeps(r.dt)
        fit = ident.motion_fit
        motion = ident.problem.motion(fit.actuator, 2 * substeps, fit.initial)
        physical.append(PhysicalReplay(r, motion, substeps, horizon, folds))
        _check_force_scale(physical[-1], r)
    numerical_part = prepared([NumericalReplay(r, horizon, folds) for r in transfers.records]) if numerical else None
    return PartReplays(prepared(physical), numerical_part)


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
