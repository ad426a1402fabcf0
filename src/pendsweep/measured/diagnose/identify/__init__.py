"""The diagnosis's first stage, identify: what the records say before any model is replayed.

* The **transfer system** of a substructured test, from the command ``y_cmd``
  to the measured platform motion ``y`` (:mod:`.transfer`, the servo's exact
  step: :mod:`.servo_step`): :func:`identify_transfers` returns, per record,
  the identification (whose motion drives the physical part's replay) and the
  measured platform derivatives compared with it, as :class:`Transfers`.
* The **oscillator's linear dynamics**, read off a replay's compared channels
  and noise (:mod:`.oscillator`): each replay computes it once
  (``Replay.identification``), and the replay stage hands it forward.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...records import Record
from .oscillator import SEPARABLE_VIF, OscillatorIdentification, identify_oscillator
from .transfer import Actuator, TransferIdentification, dominant_frequency, identify_transfer, nominal_actuator

__all__ = [
    "SEPARABLE_VIF",
    "Actuator",
    "OscillatorIdentification",
    "TransferIdentification",
    "Transfers",
    "forcing_frequency",
    "identify_oscillator",
    "identify_transfer",
    "identify_transfers",
    "nominal_actuator",
]


@dataclass
class Transfers:
    """The identify stage's result for a part-by-part diagnosis, per record (in the records' order).

    Attributes
    ----------
    records : list of Record
    transfers : list of TransferIdentification
    derivatives : list of dict
        The measured platform velocity and acceleration (``ydot``, ``yddot``, where recorded)
        against the identified motion's (:meth:`TransferIdentification.compare_derivatives`).
    """

    records: list[Record]
    transfers: list[TransferIdentification]
    derivatives: list[dict[str, dict[str, float]]]


def forcing_frequency(record: Record) -> float:
    """The frequency the actuator is judged at [Hz]: the record's forcing ``fe``, else the command's main tone."""
    if "fe" in record.forcing:
        return float(record.forcing["fe"])
    return dominant_frequency(record.channel("y_cmd"), record.dt)


def identify_transfers(records: list[Record]) -> Transfers:
    """Identify each record's transfer system (:func:`identify_transfer` at its :func:`forcing_frequency`)."""
    transfers, derivatives = [], []
    for r in records:
        ident = identify_transfer(
            r.t,
            r.channel("y_cmd"),
            r.channel("y"),
            forcing_frequency(r),
            nominal_actuator(r.actuator, r.tau),
            r.sampling("command"),
        )
        transfers.append(ident)
        derivatives.append(ident.compare_derivatives({c: r.channel(c) for c in ("ydot", "yddot") if c in r.data}))
    return Transfers(list(records), transfers, derivatives)
