"""The ``pendsweep`` command line.

Each command group lives in its own private module and registers itself on
:data:`main`; user-facing errors (:class:`pendsweep.errors.PendsweepError`)
become a one-line message, never a traceback: exit status 2 for bad input,
1 for a failure while running (:class:`pendsweep.errors.RunFailure`).
"""

import gc

from . import (
    _basins,  # noqa: F401,E402  (registers basins and map)
    _continue,  # noqa: F401,E402  (registers continue)
    _curve,  # noqa: F401,E402  (registers curve and tolerance)
    _data,  # noqa: F401,E402  (registers diagnose, fit-damping, synth)
    _figures,  # noqa: F401,E402  (registers plot, figures, params)
    _hopf,  # noqa: F401,E402  (registers the hopf command)
    _site,  # noqa: F401,E402  (registers site)
    _stability,  # noqa: F401,E402  (registers margin)
    _substructured,  # noqa: F401,E402  (registers trace and sync)
    _sweep,  # noqa: F401,E402  (registers the sweep commands)
    _wait,  # noqa: F401,E402  (registers wait)
    _warmup,  # noqa: F401,E402  (registers warmup)
)
from ._app import main

__all__ = ["main", "run"]


def run() -> None:
    """The console entry point: :data:`main`, then an exit that skips the final garbage collection.

    At exit CPython collects every tracked object, and numba's typing and
    target registries are hundreds of thousands of them: 0.25 s, a quarter
    of a one-point sweep (the plain numba script of ``make bench`` pays it
    too). Every result is written, fsynced and its lock released before the
    command returns, so freezing the heap (``gc.freeze``) loses nothing;
    exit handlers still run. Only this entry point does it, never
    :data:`main` itself, which tests and callers run in their own processes.
    """
    try:
        main()
    finally:
        gc.freeze()
