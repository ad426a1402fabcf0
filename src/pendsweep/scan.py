"""One scan engine for sweeps and Hopf scans: units, a store, resume, progress, executors.

A *scan* is a set of independent *units* of work (a sweep's ``(direction,
point, start)``, a Hopf scan's ``(mass_point, point, method)``), each with a
string key. The scan describes itself through the small :class:`Scan`
protocol; :func:`run_scan` does the rest, the same way for every kind:

1. opens the crash-safe :class:`~pendsweep.results.ResultStore` (when an
   output path is given) and reads what an earlier run finished;
2. asks the scan for the tasks that cover the unfinished units (a task may
   recompute finished units, e.g. to rebuild a batched chunk exactly as the
   first run built it; their results are dropped, not stored twice);
3. runs the tasks on an :class:`~pendsweep.executors.Executor`, writing each
   finished unit to the store at once and advancing the progress bar;
4. merges the parts into the final file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Protocol

import pandas as pd

from .executors import Executor, LocalExecutor
from .results import ResultStore


@dataclass
class UnitResult:
    """One finished unit: its key, its rows, and the state to resume from (may be empty)."""

    key: str
    rows: pd.DataFrame
    state: list[float] = field(default_factory=list)


@dataclass
class Finished:
    """What an earlier run persisted: the rows and, per finished unit key, its final state."""

    rows: pd.DataFrame
    states: dict[str, list[float]]

    @property
    def keys(self) -> set[str]:
        return set(self.states)


Task = Callable[[], Iterable[UnitResult]]


class Scan(Protocol):
    """What :func:`run_scan` needs to know about a scan."""

    #: Progress-bar label.
    desc: str
    #: Columns that identify one row; the final file is sorted by them.
    row_columns: list[str]

    def metadata(self) -> dict[str, Any]:
        """Provenance and resolved configuration (:func:`pendsweep.results.run_metadata`)."""
        ...

    def n_units(self) -> int:
        """Number of units of the whole scan."""
        ...

    def tasks(self, finished: Finished, n_jobs: int) -> tuple[list[Task], int]:
        """Tasks covering every unit not in ``finished``, and the local thread count to run them on."""
        ...

    def order(self, df: pd.DataFrame) -> pd.DataFrame:
        """The scan's rows in their final order."""
        ...


def run_scan(
    scan: Scan,
    output: Path | None = None,
    *,
    n_jobs: int = 1,
    progress: bool = False,
    overwrite: bool = False,
    executor: Executor | None = None,
) -> pd.DataFrame:
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
    """
    from tqdm.auto import tqdm

    store = ResultStore(output, scan.metadata(), scan.row_columns, overwrite=overwrite) if output is not None else None
    if store is not None:
        rows, states = store.done()
        finished = Finished(rows, states)
        if store.complete:
            return scan.order(rows)
    else:
        finished = Finished(pd.DataFrame(), {})
    done = finished.keys
    frames = [finished.rows] if not finished.rows.empty else []
    tasks, local_jobs = scan.tasks(finished, n_jobs)
    bar = tqdm(total=scan.n_units(), initial=len(done), unit="pt", disable=not progress, desc=scan.desc)
    try:
        for unit in (executor or LocalExecutor()).map_unordered(tasks, local_jobs):
            if unit.key in done:
                continue  # recomputed only to rebuild its task as the first run built it
            done.add(unit.key)
            frames.append(unit.rows)
            if store is not None:
                store.add(unit.rows, unit.key, unit.state)
            bar.update(1)
    finally:
        bar.close()
        if store is not None:
            store.flush()
    if store is not None:
        return scan.order(store.finalize())
    return scan.order(pd.concat(frames, ignore_index=True))
