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
        if self.first and getattr(sys.modules.get(name.rpartition(".")[0]), "__moved_to__", None) is None:
            return None  # not below an old package's stand-in
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
    # the studies users run, and the diagnosis (each layer's main entry points, one import away)
    "SweepConfig": ".studies.sweep",
    "run_sweep": ".studies.sweep",
    "value_range": ".studies.sweep",
    "load_sweep": ".studies.sweepfile",
    "BasinConfig": ".studies.basins",
    "run_basins": ".studies.basins",
    "MapConfig": ".studies.maps",
    "run_map": ".studies.maps",
    "HopfConfig": ".studies.hopf",
    "run_hopf": ".studies.hopf",
    "Record": ".measured.records",
    "read_record": ".measured.records",
    "write_record": ".measured.records",
    "diagnose_records": ".measured.diagnose",
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
    "BasinConfig",
    "ConfigError",
    "FIG11A",
    "FIG11B",
    "FIG8",
    "FIG9_CO",
    "FIG9_PO",
    "HopfConfig",
    "MapConfig",
    "ModelParams",
    "ParameterError",
    "PendsweepError",
    "Record",
    "ResultsError",
    "Status",
    "SweepConfig",
    "TABLE_IV",
    "__version__",
    "diagnose_records",
    "load_sweep",
    "make_backend",
    "read_record",
    "run_basins",
    "run_hopf",
    "run_map",
    "run_sweep",
    "value_range",
    "write_record",
]
