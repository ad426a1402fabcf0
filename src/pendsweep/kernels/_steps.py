"""The RK4 step of each right-hand side (CPU), built once by :func:`make_rk4_step`.

Each step has the signature ``step(x, u0, uh, u1, h, p)`` of
:func:`pendsweep.kernels._rk4.make_rk4_step`; the right-hand sides and their
tuples are documented in :mod:`pendsweep.kernels._rhs`.
"""

import numba as nb

from ._rhs import PHYSICS
from ._rk4 import make_rk4_step
from ._sincos import rotate_sincos, sincos_poly

_INLINE = nb.njit(cache=True, nogil=True, inline="always")

eq11_rk4 = make_rk4_step(PHYSICS.eq11_rhs, _INLINE)
#: Eq. (11) with sin and cos of theta once per step, rotated to the stages (the batched kernel).
eq11_rotating_rk4 = make_rk4_step(PHYSICS.eq11_rhs_trig, _INLINE, angle=2, sincos=sincos_poly, rotate=rotate_sincos)
model_rk4 = make_rk4_step(PHYSICS.model_rhs, _INLINE)
servo_rig_rk4 = make_rk4_step(PHYSICS.servo_rig_rhs, _INLINE)
pivot_pendulum_rk4 = make_rk4_step(PHYSICS.pivot_pendulum_rhs, _INLINE)
mathieu_rk4 = make_rk4_step(PHYSICS.mathieu_rhs, _INLINE)
