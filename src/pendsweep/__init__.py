"""pendsweep: bifurcation sweeps of the coupled pendulum-oscillator system.

Implements Gonzalez-Buelga, Wagg & Neild (2007), "Parametric variation of a
coupled pendulum-oscillator system using real-time dynamic substructuring".
"""

import importlib
import sys

from ._version import __version__
from .errors import ConfigError, ParameterError, PendsweepError, ResultsError


class _OldPaths:
    """0.1's module paths, kept for one release with a DeprecationWarning (:mod:`pendsweep._moved`).

    One instance goes last on :data:`sys.meta_path`, asked only for a name no
    file answers (``pendsweep.sweep``); one goes first and answers only for
    submodules of an old package (``pendsweep.site.rig``), which the file
    finders would otherwise load a second time under the old name. The
    table is imported only when an old path is used.
    """

    def __init__(self, first: bool) -> None:
        self.first = first

    def find_spec(self, name, path=None, target=None):
        if not name.startswith("pendsweep."):
            return None
        if self.first:
            package = name.rpartition(".")[0]
            parent = sys.modules.get(package)
            if parent is None or parent.__name__ == package:
                return None  # not below an old package's alias
        from ._moved import find_spec

        return find_spec(name)


if not any(isinstance(finder, _OldPaths) for finder in sys.meta_path):
    sys.meta_path.insert(0, _OldPaths(first=True))
    sys.meta_path.append(_OldPaths(first=False))

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
