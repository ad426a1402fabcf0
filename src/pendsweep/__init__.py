"""pendsweep: bifurcation sweeps of the coupled pendulum-oscillator system.

Implements Gonzalez-Buelga, Wagg & Neild (2007), "Parametric variation of a
coupled pendulum-oscillator system using real-time dynamic substructuring".
"""

from ._version import __version__
from .backends import BACKENDS, make_backend
from .errors import ConfigError, ParameterError, PendsweepError, ResultsError
from .params import FIG8, FIG9_CO, FIG9_PO, FIG11A, FIG11B, TABLE_IV, ModelParams
from .status import Status

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
