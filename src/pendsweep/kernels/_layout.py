"""Status codes and per-period record layout shared by every kernel.

Kernels return integer status codes only; :mod:`pendsweep.backends.status` turns them
into names and messages. A record row holds one forcing period.
"""

import numba as nb

from ..model.params import KERNEL_FIELDS

# Status codes returned by kernels.
STATUS_OK = 0
STATUS_DIVERGED = 1  # state became non-finite
STATUS_UNSTABLE = 2  # loop instability detected (substructured backend)

# Columns of a per-period record row (float64).
REC_THETA_PEAK = 0  # signed wrapped theta of largest |theta| in the period [rad]
REC_THETA_ABSMAX = 1  # max |wrapped theta| in the period [rad]
REC_Y_SEC = 2  # stroboscopic section at the period's end (forcing phase 0)
REC_YDOT_SEC = 3
REC_THETA_SEC = 4  # wrapped to (-pi, pi]
REC_THETADOT_SEC = 5
REC_Y_ABSMAX = 6  # max |y| in the period [m]
REC_ROTATIONS = 7  # net full rotations in the period (signed count)
N_RECORD_COLUMNS = 8

RECORD_COLUMNS = (
    "theta_peak",
    "theta_absmax",
    "y_sec",
    "ydot_sec",
    "theta_sec",
    "thetadot_sec",
    "y_absmax",
    "rotations",
)
#: Column index by name, for code outside the kernels (``RECORD_INDEX["y_sec"]``).
RECORD_INDEX = {name: i for i, name in enumerate(RECORD_COLUMNS)}
#: The Poincare-section columns (y, ydot, theta, thetadot) of a record row.
SECTION_COLUMNS = slice(RECORD_INDEX["y_sec"], RECORD_INDEX["thetadot_sec"] + 1)

# Index of each parameter in the kernel parameter vector, looked up in its one
# declaration (the kernel fields of ModelParams, see params.KERNEL_FIELDS).
P_M_PEND, P_L, P_B1, P_B2, P_B3, P_G, P_M, P_C, P_K, P_K3 = (
    KERNEL_FIELDS.index(name) for name in ("m", "l", "b1", "b2", "b3", "g", "M", "C", "K", "k3")
)
N_PARAMS = len(KERNEL_FIELDS)


@nb.njit(cache=True, nogil=True, inline="always")
def pendulum_params(p):
    """The pendulum's ``(m, l, b1, b2, b3, g)`` from kernel parameter vector ``p`` (every pendulum equation's tuple)."""
    return p[P_M_PEND], p[P_L], p[P_B1], p[P_B2], p[P_B3], p[P_G]


@nb.njit(cache=True, nogil=True, inline="always")
def model_params(p, M2, C2):
    """The numerical model's ``(M1, C1, K, k3)``: the oscillator less the rig's platform ``(M2 [kg], C2 [kg/s])``."""
    return p[P_M] - M2, p[P_C] - C2, p[P_K], p[P_K3]
