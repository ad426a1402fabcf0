"""Numba kernels. Pure functions of floats and contiguous float64 arrays.

Set ``NUMBA_DISABLE_JIT=1`` to run them as plain Python (for coverage or
debugging); results are identical, only slower.
"""

from ._emulated import emulated_periods, emulated_rhs, emulated_step, emulated_trace, forcing_table
from ._layout import (
    N_RECORD_COLUMNS,
    RECORD_COLUMNS,
    STATUS_DIVERGED,
    STATUS_OK,
    STATUS_UNSTABLE,
)
from ._measured import driven_trace, pendulum_trace, substructured_replay
from ._records import wrap_angle

__all__ = [
    "N_RECORD_COLUMNS",
    "RECORD_COLUMNS",
    "STATUS_DIVERGED",
    "STATUS_OK",
    "STATUS_UNSTABLE",
    "emulated_periods",
    "emulated_rhs",
    "emulated_step",
    "emulated_trace",
    "driven_trace",
    "pendulum_trace",
    "substructured_replay",
    "forcing_table",
    "wrap_angle",
]
