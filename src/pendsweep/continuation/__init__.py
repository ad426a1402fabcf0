"""Periodic orbits by continuation: shooting, Newton, pseudo-arclength, bifurcations (issue 15).

* :mod:`.core` - generic pseudo-arclength continuation of fixed points of a
  map with its Jacobian; fold, period-doubling and Neimark-Sacker detection
  and location; branch switching at period doublings.
* :mod:`.shooting` - the stroboscopic map of Eq. (11) and its monodromy
  matrix from the variational equations.
"""

from .core import (
    BRANCH_POINT,
    FOLD,
    NEIMARK_SACKER,
    PERIOD_DOUBLING,
    Bifurcation,
    Branch,
    Continuation,
    ContinuationError,
    Evaluation,
    Point,
    Result,
    Settings,
    newton,
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
