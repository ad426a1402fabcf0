"""Periodic orbits by continuation: shooting, Newton, pseudo-arclength, bifurcations (issue 15).

* :mod:`.core` - generic pseudo-arclength continuation of fixed points of a
  map with its Jacobian; fold, period-doubling and Neimark-Sacker detection
  and location; branch switching at period doublings.
* :mod:`.problem` - what it works on and produces (the map problem, settings,
  points, branches, bifurcation labels); :mod:`.algebra` - Newton, the null
  tangent and the test functions in scaled variables.
* :mod:`.shooting` - the stroboscopic map of Eq. (11) and its monodromy
  matrix from the variational equations.
"""

from .algebra import newton
from .core import Continuation
from .problem import (
    BRANCH_POINT,
    FOLD,
    NEIMARK_SACKER,
    PERIOD_DOUBLING,
    Bifurcation,
    Branch,
    ContinuationError,
    Evaluation,
    Point,
    Result,
    Settings,
)
from .shooting import PendulumShooting, semi_trivial_section

__all__ = [
    "BRANCH_POINT",
    "FOLD",
    "NEIMARK_SACKER",
    "PERIOD_DOUBLING",
    "Bifurcation",
    "Branch",
    "Continuation",
    "ContinuationError",
    "Evaluation",
    "PendulumShooting",
    "Point",
    "Result",
    "Settings",
    "newton",
    "semi_trivial_section",
]
