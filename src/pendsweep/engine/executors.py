"""Where independent chunks of work run: this process, or a Dask cluster.

A *task* is a zero-argument callable returning an iterable of results (for
a sweep: finished points). An executor runs a list of tasks and yields their
results as they come, in the caller's thread, so the caller can write each
one to its crash-safe :class:`~pendsweep.engine.results.ResultStore` at once.

``local``
    Threads in this process (the numba kernels release the GIL).
``dask``
    Each task is shipped to a ``dask.distributed`` worker and its results
    come back when the task is finished. A worker lost mid-task costs that
    task only: the scheduler reruns it elsewhere and the caller receives its
    results once, so nothing is lost or duplicated; results already written
    stay valid. Sweeps (and Hopf scans, through the same two calls
    :func:`make_executor` and :meth:`Executor.map_unordered`) pick the
    cluster with ``--executor dask --scheduler tcp://HOST:8786`` or the
    environment variable :data:`SCHEDULER_ENV`.
"""

from __future__ import annotations

import os
import queue
import threading
from collections.abc import Callable, Iterable, Iterator
from typing import Any, Protocol

from ..errors import ConfigError

Task = Callable[[], Iterable[Any]]

#: Environment variable naming the Dask scheduler when ``--scheduler`` is not given.
SCHEDULER_ENV = "PENDSWEEP_SCHEDULER"
EXECUTORS = ("local", "dask")


class Executor(Protocol):
    name: str

    def map_unordered(self, tasks: list[Task], n_jobs: int = 1) -> Iterator[Any]:
        """Run ``tasks``; yield every result of every task as it becomes available."""
        ...

    def close(self) -> None: ...


class LocalExecutor:
    """Run tasks on ``n_jobs`` threads of this process (joblib's threading backend).

    Any exception, raised by a task or by the thread pool itself, is raised
    again in the caller's thread; the caller never waits on a dead runner.
    """

    name = "local"

    def map_unordered(self, tasks: list[Task], n_jobs: int = 1) -> Iterator[Any]:
        if n_jobs == 1 or len(tasks) <= 1:
            for task in tasks:
                yield from task()
            return
        from joblib import Parallel, delayed  # imported on first parallel use: joblib costs ~0.2 s at start-up

        items: queue.Queue = queue.Queue()
        finished = object()  # put once, after every task ended or the pool failed

        def drain(task):
            for item in task():
                items.put((None, item))

        def run_all():
            try:
                Parallel(n_jobs=n_jobs, backend="threading")(delayed(drain)(t) for t in tasks)
            except BaseException as exc:  # re-raised in the caller's thread
                items.put((exc, None))
            finally:
                items.put((finished, None))

        runner = threading.Thread(target=run_all, daemon=True)
        runner.start()
        while True:
            error, item = items.get()
            if error is finished:
                break
            if error is not None:
                raise error
            yield item
        runner.join()

    def close(self) -> None:
        pass


def _run_task(task: Task) -> list[Any]:
    """Worker side of :class:`DaskExecutor`: run a task to completion."""
    return list(task())


class DaskExecutor:
    """Ship each task to a ``dask.distributed`` worker; stream results back.

    Parameters
    ----------
    scheduler : str or distributed.Client, optional
        Scheduler address (``tcp://host:8786``) or an existing client;
        default: the :data:`SCHEDULER_ENV` environment variable.
    timeout : str
        How long to try reaching the scheduler (Dask time string).
    """

    name = "dask"

    def __init__(self, scheduler: Any = None, timeout: str = "10s") -> None:
        try:
            from distributed import Client
        except ImportError:
            raise ConfigError("--executor dask needs dask.distributed: pip install 'pendsweep[cluster]'") from None
        if isinstance(scheduler, Client):
            self.client, self._owned = scheduler, False
            return
        address = scheduler or os.environ.get(SCHEDULER_ENV)
        if not address:
            raise ConfigError(
                f"--executor dask needs a scheduler: give --scheduler tcp://HOST:PORT or set {SCHEDULER_ENV}"
            )
        try:
            self.client, self._owned = Client(address, timeout=timeout, set_as_default=False), True
        except (OSError, TimeoutError) as exc:
            raise ConfigError(f"cannot reach the Dask scheduler at {address!r}: {exc}") from None

    def map_unordered(self, tasks: list[Task], n_jobs: int = 1) -> Iterator[Any]:
        from distributed import as_completed

        futures = [self.client.submit(_run_task, task, pure=False) for task in tasks]
        try:
            # Our client is not the default one (set_as_default=False): name its loop.
            for future in as_completed(futures, loop=self.client.loop):
                results = future.result()
                future.release()
                yield from results
        finally:
            self.client.cancel([f for f in futures if not f.done()])

    def close(self) -> None:
        if self._owned:
            self.client.close()


def make_executor(name: str = "local", scheduler: Any = None) -> Executor:
    """The executor called ``name`` (``local`` or ``dask``); see the module docstring."""
    if name == "local":
        if scheduler:
            raise ConfigError("--scheduler applies to --executor dask only")
        return LocalExecutor()
    if name == "dask":
        return DaskExecutor(scheduler)
    raise ConfigError(f"executor = {name!r}; choose one of {', '.join(EXECUTORS)}")
