"""One scan engine for sweeps and Hopf scans: units, a store, resume, progress, executors.

A *scan* is a set of independent *units* of work (a sweep's ``(direction,
point, start)``, a Hopf scan's ``(mass_point, point, method)``), each with a
string key. The scan describes itself through the small :class:`Scan`
protocol; :func:`run_scan` does the rest, the same way for every kind:

1. checks the number of local jobs and the work estimate (integration steps,
   :meth:`Scan.work`) against a limit, before anything else;
2. opens the crash-safe :class:`~pendsweep.engine.results.ResultStore` (when an
   output path is given; it takes the output's lock, so a second process
   writing the same output is refused) and reads what an earlier run finished;
3. asks the scan for the tasks that cover the unfinished units (a task may
   recompute finished units, e.g. to rebuild a batched chunk exactly as the
   first run built it; their results are dropped, not stored twice);
4. runs the tasks on an :class:`~pendsweep.engine.executors.Executor`, writing each
   finished unit to the store at once and advancing the progress bar;
5. merges the parts into the final file and releases the lock.

With an output file, rows are not gathered while the scan runs: each unit
goes to the store, which holds at most its buffer until the next checkpoint
(and writes it as one part of many units), and the merge streams the parts
into the final file a part at a time. A
caller that wants no rows back (``return_rows=False``, e.g. a command that
summarises a few columns read back from the file) therefore never holds all
of them; a resumed run reads back only :attr:`Scan.resume_columns`.

Resume is bit-identical when every task computes its units the same way
whichever units were already done: scans cut their tasks from the full unit
list by index and rerun a partly finished task whole (see
:meth:`pendsweep.studies.sweep.SweepScan.tasks`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from ..errors import ConfigError
from .executors import Executor, LocalExecutor

if TYPE_CHECKING:  # imported where used: pandas and pyarrow cost start-up time
    import pandas as pd
    import pyarrow as pa

    from .results import ResultStore


@dataclass
class UnitResult:
    """One finished unit: its key, its rows, and the state to resume from (may be empty)."""

    key: str
    rows: pa.Table | pd.DataFrame
    state: list[float] = field(default_factory=list)


@dataclass
class Finished:
    """What an earlier run persisted: the rows and, per finished unit key, its final state."""

    rows: pa.Table
    states: dict[str, list[float]]

    @property
    def keys(self) -> set[str]:
        return set(self.states)


Task = Callable[[], Iterable[UnitResult]]


def check_unit_keys(finished: Finished, keys: set[str]) -> None:
    """Refuse to resume from units this scan would not make (units of another size: another version or device).

    Their starts would otherwise be taken as done while only part of them
    are, and the file would come out short without a word.
    """
    foreign = sorted(finished.keys - keys)
    if foreign:
        raise ConfigError(
            f"the parts on disk hold {len(foreign)} unit(s) this run would cut otherwise (e.g. {foreign[0]!r}: "
            "units of another size, from another pendsweep version or device); rerun with --overwrite"
        )


#: Memory per result row of a per-start scan (basins, map) when gathered [bytes]: about 25 columns
#: of 8 bytes in Arrow, and as much again while the final table and its summary are built.
RESULT_ROW_BYTES = 512
#: Largest work estimate [integration steps] run without ``--max-work`` or ``--yes``
#: (about 3 core-minutes of the batched emulated kernel, hours of the substructured loop).
DEFAULT_MAX_WORK = 1e10
#: The same for basin and parameter maps, whose estimate counts every start to its cap (early stop does
#: 10-30 % of it): about a day of the batched kernel on a 2-core machine at the measured ~10 ns per step.
PER_START_MAX_WORK = 1e13
#: The same for backends that run one start at a time (the substructured loop, about 1e6 steps a
#: second): about a day of it.
UNBATCHED_PER_START_MAX_WORK = 1e11


def per_start_max_work(backend: str) -> float:
    """The default work limit of a basin or parameter map on ``backend`` (a day at its measured rate)."""
    from ..backends import BACKENDS

    return PER_START_MAX_WORK if getattr(BACKENDS.get(backend), "batched", True) else UNBATCHED_PER_START_MAX_WORK


@dataclass(frozen=True)
class Work:
    """A scan's work estimate: ``units x periods x steps (+ other)`` integration steps.

    Attributes
    ----------
    units : int
        Integrations (points x starts x branches; Hopf: points x trial amplitudes).
    periods : float
        Forcing periods per integration.
    steps : float
        Integration steps per forcing period (mean over the points).
    other : float
        Steps of work that is not a forcing-period integration (e.g. Floquet monodromies).
    result_bytes : float
        Memory the results take when gathered [bytes] (0: not estimated).
    """

    units: int
    periods: float
    steps: float
    other: float = 0.0
    result_bytes: float = 0.0

    @property
    def total(self) -> float:
        return self.units * self.periods * self.steps + self.other

    def describe(self, runs: str = "runs") -> str:
        """The estimate in words, its runs called ``runs``; "x 1 periods" left out for runs that are not periodic."""
        if not self.units:  # only work that is not a run of forcing periods (Floquet monodromies)
            return f"{self.total:.3g} integration steps"
        periods = f" x {self.periods:.4g} periods" if self.periods != 1 else ""
        text = f"{self.total:.3g} integration steps ({self.units} {runs}{periods} x {self.steps:.4g} steps"
        return text + (f" + {self.other:.3g} other)" if self.other else ")")


def machine_memory() -> float:
    """Physical memory of this machine [bytes] (inf where the system does not say)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return math.inf


def check_work(work: Work, max_work: float | None, what: str = "scan", runs: str = "runs") -> None:
    """Refuse (``ConfigError``, exit 2) a scan whose estimate exceeds ``max_work`` or the machine's memory.

    None lifts both limits (``--yes``). ``what`` and ``runs`` name the job and
    its runs in the message (e.g. ``"diagnosis"``, ``"replays"``).
    """
    if max_work is None:
        return
    memory = machine_memory()
    if work.result_bytes > memory:
        raise ConfigError(
            f"this {what}'s results need about {work.result_bytes / 2**30:.3g} GiB of memory"
            + (f" ({work.units} {runs})" if work.units else "")
            + ", "
            f"more than this machine's {memory / 2**30:.3g} GiB; make it smaller (or pass --yes to try anyway)"
        )
    if work.total > max_work:
        raise ConfigError(
            f"this {what} needs about {work.describe(runs)}, more than the limit of {max_work:.3g}; "
            f"pass --max-work {_round_up(work.total)} (or --yes) to run it"
        )


def _round_up(x: float) -> str:
    """``x`` rounded up to one significant digit, e.g. ``2e11``."""
    exponent = math.floor(math.log10(x)) if x > 0 else 0
    mantissa = math.ceil(x / 10**exponent * (1 - 1e-12))
    if mantissa == 10:
        mantissa, exponent = 1, exponent + 1
    return f"{mantissa}e{exponent}"


def check_jobs(n_jobs: int) -> None:
    """Accept ``n_jobs`` = -1 (all cores) or 1..1024 local workers; else ``ConfigError`` (exit 2)."""
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or not (n_jobs == -1 or 1 <= n_jobs <= 1024):
        raise ConfigError(f"--jobs = {n_jobs!r}: give a number of workers from 1 to 1024, or -1 for all cores")


def sample_indices(n: int, at_most: int = 101) -> list[int]:
    """Up to ``at_most`` indices spread evenly over ``range(n)`` (ends included), for estimates."""
    if n <= at_most:
        return list(range(n))
    return sorted({round(k * (n - 1) / (at_most - 1)) for k in range(at_most)})


class Scan(Protocol):
    """What :func:`run_scan` needs to know about a scan."""

    #: Progress-bar label.
    desc: str
    #: Columns that identify one row; the final file is sorted by them.
    row_columns: list[str]
    #: Columns of the finished rows that :meth:`tasks` reads from ``Finished.rows`` on a resume,
    #: besides the row columns (empty: no finished rows are read back, only their final states).
    resume_columns: list[str]

    def metadata(self) -> dict[str, Any]:
        """Provenance and resolved configuration (:func:`pendsweep.engine.results.run_metadata`)."""
        ...

    def n_units(self) -> int:
        """Number of units of the whole scan."""
        ...

    def work(self) -> Work:
        """Estimated integration work of the whole scan."""
        ...

    def tasks(self, finished: Finished, n_jobs: int) -> tuple[list[Task], int]:
        """Tasks covering every unit not in ``finished``, and the local thread count to run them on."""
        ...

    def order(self, df: pd.DataFrame) -> pd.DataFrame:
        """The scan's rows in their final order (the frame :func:`run_scan` returns)."""
        ...


def run_scan(
    scan: Scan,
    output: Path | None = None,
    *,
    n_jobs: int = 1,
    progress: bool = False,
    overwrite: bool = False,
    executor: Executor | None = None,
    max_work: float | None = DEFAULT_MAX_WORK,
    as_frame: bool = True,
    checkpoint_seconds: float = 1.0,
    return_rows: bool = True,
) -> pd.DataFrame | pa.Table | None:
    """Run (or resume) ``scan`` and return its rows in order (module docstring).

    Parameters
    ----------
    scan : Scan
    output : Path, optional
        Parquet file. Finished units are persisted as they come and a rerun
        with the same configuration resumes; without it rows are only returned.
    n_jobs : int
        Local workers (-1: all cores), as the scan's tasks use them.
    progress : bool
        Progress bar (units done, rate, ETA) on stderr.
    overwrite : bool
        Discard earlier results at ``output`` instead of resuming.
    executor : Executor, optional
        Where tasks run (default: threads of this process).
    max_work : float or None
        Refuse scans whose work estimate exceeds this many integration steps
        (None: no limit).
    as_frame : bool
        True: a pandas DataFrame in the scan's order (:meth:`Scan.order`).
        False: a pyarrow Table sorted by the scan's row columns (no frame is
        built; the rows stay in the columns the scan made them in).
    checkpoint_seconds : float
        With ``output``: a finished unit is persisted at most this many
        seconds after it finishes (0: at once; each write costs two fsyncs),
        together with every unit that finished meanwhile. A run killed later
        loses none of it.
    return_rows : bool
        False (with ``output`` only): return None and hold no more rows than
        the store's buffer and about two row groups of the merge (a few MiB);
        read what is needed
        back from ``output`` (e.g. a few columns with ``pq.read_table(output,
        columns=...)``).

    Raises
    ------
    ConfigError
        Bad ``n_jobs``, or more work than ``max_work``.
    pendsweep.engine.results.OutputLocked
        Another process is writing ``output``.
    """
    from .columns import read_parquet, sort_rows
    from .results import ResultStore, concat_rows

    check_jobs(n_jobs)
    check_work(scan.work(), max_work)
    if not (isinstance(checkpoint_seconds, (int, float)) and 0 <= checkpoint_seconds < math.inf):
        raise ConfigError(
            f"--checkpoint-seconds = {checkpoint_seconds!r}: give a finite number of seconds >= 0 (0: write every unit)"
        )
    if output is None:
        if not return_rows:
            raise ConfigError("return_rows=False needs an output file to hold the rows")
        rows = _run(scan, None, Finished(concat_rows([]), {}), n_jobs, progress, executor)
    else:
        store = ResultStore(
            output, scan.metadata(), scan.row_columns, overwrite=overwrite, flush_seconds=checkpoint_seconds
        )
        try:
            if store.complete:
                rows = read_parquet(output) if return_rows else None
            else:
                finished = Finished(*store.done(scan.resume_columns))
                rows = _run(scan, store, finished, n_jobs, progress, executor, return_rows)
        finally:
            store.close()
    if rows is None:
        return None
    if as_frame:
        return scan.order(rows.to_pandas())
    return sort_rows(rows, list(scan.row_columns)) if output is None else rows  # a store's rows come sorted


def _run(
    scan: Scan, store: ResultStore | None, finished: Finished, n_jobs, progress, executor, return_rows: bool = True
) -> pa.Table | None:
    """Run the unfinished units; every row (earlier ones included) as one table, or None when not ``return_rows``.

    Without a store the rows are gathered here; with one they go only to
    the store and come back from its final file.
    """
    from .results import as_table, concat_rows

    done = finished.keys
    tables = [finished.rows]  # gathered only without a store
    tasks, local_jobs = scan.tasks(finished, n_jobs)
    bar = progress_bar(progress, total=scan.n_units(), initial=len(done), unit="pt", desc=scan.desc)
    try:
        for unit in (executor or LocalExecutor()).map_unordered(tasks, local_jobs):
            if unit.key in done:
                continue  # recomputed only to rebuild its task as the first run built it
            done.add(unit.key)
            rows = as_table(unit.rows)
            if store is None:
                tables.append(rows)
            else:
                store.add(rows, unit.key, unit.state)
            bar.update(1)
    except BaseException:
        if store is not None:
            store.flush()  # what finished stays for a resume
        raise
    finally:
        bar.close()
    if store is not None:
        return store.finalize(return_rows)
    return concat_rows(tables)


class _NoBar:
    """What :func:`progress_bar` gives when there is no bar to show."""

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def progress_bar(progress: bool, **options: Any):
    """A tqdm bar with ``options`` when ``progress``, else a stand-in (tqdm costs 40 to 70 ms of start-up)."""
    if not progress:
        return _NoBar()
    from tqdm.auto import tqdm

    return tqdm(**options)
