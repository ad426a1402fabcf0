"""Numba kernels. Pure functions of floats and contiguous float64 arrays.

Layout: every right-hand side is written once, as a plain function, in
:mod:`._rhs`; :mod:`._rk4` builds the one RK4 step over any of them and
:mod:`._steps` holds the step of each. The kernels (:mod:`._emulated`,
:mod:`._batched`, :mod:`._substructured`, :mod:`._measured`,
:mod:`._mathieu`) only arrange steps, inputs and records; :mod:`._layout`
declares status codes, record columns and the parameter vector.

Set ``NUMBA_DISABLE_JIT=1`` to run them as plain Python (for coverage or
debugging); results are identical, only slower.
"""

# numba reads its CPU tuning once, when it builds its code generator: before any kernel module is imported
from ._vector_width import WIDE_VECTORS

# isort: split
from ._emulated import emulated_periods, emulated_trace, eq11_params, eq11_step, forcing_table
from ._layout import (
    N_RECORD_COLUMNS,
    RECORD_COLUMNS,
    STATUS_DIVERGED,
    STATUS_OK,
    STATUS_UNSTABLE,
)
from ._measured import driven_trace, pendulum_trace, substructured_replay
from ._notice import announce_compilation
from ._records import wrap_angle
from ._rhs import PHYSICS, compile_physics

__all__ = [
    "N_RECORD_COLUMNS",
    "PHYSICS",
    "RECORD_COLUMNS",
    "STATUS_DIVERGED",
    "STATUS_OK",
    "STATUS_UNSTABLE",
    "WIDE_VECTORS",
    "compile_physics",
    "driven_trace",
    "emulated_periods",
    "emulated_trace",
    "eq11_params",
    "eq11_step",
    "forcing_table",
    "pendulum_trace",
    "substructured_replay",
    "wrap_angle",
]

announce_compilation()  # numba compiles a kernel at its first call, after this
