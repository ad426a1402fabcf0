"""The ``pendsweep`` command line.

Each command group lives in its own private module and registers itself on
:data:`main`; user-facing errors (:class:`pendsweep.errors.PendsweepError`)
become a one-line message, never a traceback: exit status 2 for bad input,
1 for a failure while running (:class:`pendsweep.errors.RunFailure`).
"""

from . import (
    _basins,  # noqa: F401,E402  (registers basins and map)
    _continue,  # noqa: F401,E402  (registers continue)
    _data,  # noqa: F401,E402  (registers diagnose, fit-damping, synth)
    _hopf,  # noqa: F401,E402  (registers the hopf command)
    _stability,  # noqa: F401,E402  (registers margin)
    _substructured,  # noqa: F401,E402  (registers trace and sync)
    _sweep,  # noqa: F401,E402  (registers the sweep commands)
)
from ._app import main

__all__ = ["main"]
