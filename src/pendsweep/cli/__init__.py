"""The ``pendsweep`` command line.

Each command group lives in its own private module and registers itself on
:data:`main`; user-facing errors (:class:`pendsweep.errors.PendsweepError`)
become a one-line message and exit status 2, never a traceback.
"""

from ._app import main
from . import _sweep  # noqa: F401,E402  (registers the sweep commands)
from . import _hopf  # noqa: F401,E402  (registers the hopf command)
from . import _substructured  # noqa: F401,E402  (registers trace and sync)
from . import _stability  # noqa: F401,E402  (registers margin)
from . import _data  # noqa: F401,E402  (registers diagnose, fit-damping, synth)
from . import _continue  # noqa: F401,E402  (registers continue)
from . import _basins  # noqa: F401,E402  (registers basins and map)

__all__ = ["main"]
