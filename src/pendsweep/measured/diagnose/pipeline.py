"""The diagnosis as one pipeline: identify, replay, fit, judge, report.

Each stage is one module or sub-package, entered once per diagnosis, and
hands its result forward:

1. **identify** (:mod:`.identify`): the transfer system of a substructured
   test, :class:`~.identify.Transfers`; the oscillator's linear dynamics,
   read off each replay's record (:mod:`.identify.oscillator`);
2. **replay** (:mod:`.replay`): the records' models driven by their recorded
   inputs, :class:`~.replay.Replayed` (with each replay's oscillator
   identification);
3. **fit** (:mod:`.fit`): the nominal model and every candidate fitted and
   cross-validated, the second round's pairs, ranked: :class:`~.fit.Fits`;
4. **judge** (:mod:`.judge`): the tests and the verdict, :class:`~.judge.Diagnosis`
   (or :class:`~.judge.PartsDiagnosis`);
5. **report** (:mod:`.report`): the markdown report, figures and extended
   model of either.

:func:`diagnose` runs replay, fit and judge on replays the caller made;
:func:`diagnose_parts` runs identify, replay, fit and judge on a
substructured test's records.

:func:`diagnose_parts` answers the lab engineer's question when a hybrid test
goes wrong: blame the numerical model, the specimen or the actuator? It

1. identifies the **transfer system** from the command ``y_cmd`` to the
   measured platform displacement ``y`` (:mod:`.identify.transfer`; its verdict: :mod:`.judge.parts`) and compares it
   with the record's nominal actuator at the forcing frequency;
2. replays the **physical substructure** driven by the identified platform
   motion, against the encoder and the load cell (:class:`.replay.PhysicalReplay`);
3. replays the **numerical model** driven by the forces the controller was
   given, against its own output (:class:`.replay.NumericalReplay`; records
   without ``Fe``, such as an experimental site's log, skip this part);

each with the causes that belong to it (:data:`.effects.PART_OF`). A cause
is named for the part whose own replay it explains; the verdict is every
named cause, and the report says which part each belongs to.
"""

from __future__ import annotations

from threadpoolctl import threadpool_limits

from ...engine.scan import Work
from ...errors import ConfigError
from ..records import Record
from .effects import ACTUATOR_CAUSES, PART_OF
from .fit import BEAM, DIAGNOSIS_BYTES_PER_SAMPLE, FIT_EVALUATIONS, PARTNERS, diagnosis_work, fit_candidates
from .identify import identify_transfers
from .judge import Diagnosis, PartsDiagnosis, judge, judge_parts
from .replay import Replay, physical_substeps, prepared, replay_parts

#: Channels a record needs for each part.
PART_CHANNELS = {"transfer": ("y_cmd", "y"), "physical": ("theta", "Fs"), "numerical": ("Fe",)}


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
        return judge(fit_candidates(prepared(replays), causes, n_jobs))


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


def missing_parts(record: Record) -> list[str]:
    """The columns ``record`` lacks for a part-by-part diagnosis (command, motion, angle, load cell)."""
    return [c for c in PART_CHANNELS["transfer"] + PART_CHANNELS["physical"] if c not in record.data]


def has_parts(record: Record) -> bool:
    """Whether ``record`` holds what the part-by-part diagnosis needs."""
    return not missing_parts(record)


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
        if missing := missing_parts(r):
            raise ConfigError(f"{r.name}: a part-by-part diagnosis needs column(s) {', '.join(missing)}")
    wanted = None if causes is None else set(causes)
    unknown = sorted((wanted or set()) - set(PART_OF))
    if unknown:
        raise ConfigError(f"cause(s) {', '.join(unknown)} do not apply to a substructured test's parts; "
                          f"applicable: {', '.join(sorted(PART_OF))}")  # fmt: skip
    numerical = all("Fe" in r.data for r in records)

    def restricted(part: str) -> list[str] | None:
        if wanted is None:
            return None
        return [c for c in sorted(wanted) if PART_OF[c] == part or (part == "physical" and c in _PHYSICAL_CHAIN)]

    skipped: dict[str, str] = {}
    physical_causes, numerical_causes = restricted("physical"), restricted("numerical")
    if physical_causes == []:
        skipped["physical"] = "--cause named none of its causes"
    if not numerical:
        skipped["numerical"] = "the record has no Fe, the numerical model's input (an experimental site's log)"
    elif numerical_causes == []:
        skipped["numerical"] = "--cause named none of its causes"
    transfers = identify_transfers(records)
    replayed = replay_parts(transfers, horizon, folds, numerical="numerical" not in skipped)
    # The fits' tall, thin SVDs run several times faster on one BLAS thread (see diagnose).
    with threadpool_limits(1, user_api="blas"):
        physical = None if "physical" in skipped else fit_candidates(replayed.physical, physical_causes, n_jobs)
        numerical_fits = (
            None if replayed.numerical is None else fit_candidates(replayed.numerical, numerical_causes, n_jobs)
        )
        return judge_parts(transfers, physical, numerical_fits, skipped, wanted)


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
    if _by_parts(records, method):
        return diagnose_parts(records, causes, n_jobs, horizon, folds)
    return diagnose([Replay(r, horizon, folds) for r in records], causes, n_jobs)


def diagnosis_work_of(records: list[Record], causes: list[str] | None = None, method: str = "parts") -> Work:
    """The work estimate of :func:`diagnose_records` with the same arguments."""
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
        raise ConfigError(
            f"{lacking.name}: no {', '.join(missing_parts(lacking))} column: a part-by-part diagnosis needs the load cell and the "
            "encoder; pass --method closed-loop to replay the whole loop instead"
        )
    if "rig" in kinds:
        raise ConfigError(f"{records[0].name}: a rig record (a site log) is diagnosed part by part only")
    return False
