"""pendsweep: bifurcation sweeps of the coupled pendulum-oscillator system.

Implements Gonzalez-Buelga, Wagg & Neild (2007), "Parametric variation of a
coupled pendulum-oscillator system using real-time dynamic substructuring".
"""

import importlib

from . import _moved
from ._version import __version__
from .errors import ConfigError, ParameterError, PendsweepError, ResultsError

_moved.install()  # 0.1's module paths keep working for one release, with a DeprecationWarning

# Exports from modules that pull in numpy, pandas, scipy or the numba kernels are
# imported on first use (PEP 562), so that `pendsweep --help` starts in a blink.
_LAZY = {
    "BACKENDS": ".backends",
    "make_backend": ".backends",
    "FIG8": ".model.params",
    "FIG9_CO": ".model.params",
    "FIG9_PO": ".model.params",
    "FIG11A": ".model.params",
    "FIG11B": ".model.params",
    "TABLE_IV": ".model.params",
    "ModelParams": ".model.params",
    "Status": ".backends.status",
}


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


__all__ = [
    "BACKENDS",
    "ConfigError",
    "FIG8",
    "FIG9_CO",
    "FIG9_PO",
    "FIG11A",
    "FIG11B",
    "ModelParams",
    "ParameterError",
    "PendsweepError",
    "ResultsError",
    "Status",
    "TABLE_IV",
    "__version__",
    "make_backend",
]
