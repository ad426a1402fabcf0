"""The classical fourth-order Runge-Kutta step, written once for every system.

:func:`make_rk4_step` turns a right-hand side ``rhs(x, u, p)`` (state tuple,
input at the stage time, parameter tuple; returns the derivative tuple) into
a step ``step(x, u0, uh, u1, h, p)`` with the inputs at the step's start,
midpoint and end, as in numbakit-ode: the step is built once per right-hand
side, as a closure, and inlined where it is called. Inputs (forcing,
commanded displacement, pivot acceleration, Mathieu stiffness) are known
functions of time supplied by the caller, so one step serves the emulated
system, the numerical model, the rig and the Floquet system alike.

A right-hand side that needs the sine and cosine of one angle coordinate
(Eq. (11)) can have them carried by the step instead (``angle``): they are
evaluated once, at the step's start, and rotated to the later stages, whose
angles differ from it by the stage increments (a quarter of the sin/cos work
of evaluating them per stage; :func:`pendsweep.kernels._sincos.rotate_sincos`).
"""

from ._tuple import axpy, rk4_combine


def make_rk4_step(rhs, jit, angle=None, sincos=None, rotate=None):
    """RK4 step over ``rhs`` compiled with decorator ``jit``.

    Parameters
    ----------
    rhs : callable
        ``rhs(x, u, p) -> dx/dt`` with ``x`` and the result tuples of equal
        length; with ``angle``, ``rhs(x, trig, u, p)`` with ``trig = (sin
        x[angle], cos x[angle])``.
    jit : callable
        Decorator compiling the step (for example ``numba.njit(inline="always")``
        or a CUDA device decorator); ``rhs`` must be compiled for the same target.
    angle : int, optional
        Index of the angle coordinate whose sine and cosine the step carries.
    sincos, rotate : callable, optional
        With ``angle``: ``sincos(a) -> (sin a, cos a)`` at the step's start,
        and ``rotate(trig, d)``, the sine and cosine of the angle ``d``
        further on, for the stages at ``x + (h/2) k1``, ``x + (h/2) k2``
        and ``x + h k3``. Compiled for the same target.

    Returns
    -------
    callable
        ``step(x, u0, uh, u1, h, p) -> x(t + h)``: stages at ``t``, ``t + h/2``
        (twice) and ``t + h`` with inputs ``u0``, ``uh``, ``uh``, ``u1``.
        Both forms take the same stages with the same weights.
    """
    if angle is None:

        def rk4_step(x, u0, uh, u1, h, p):
            half = 0.5 * h
            k1 = rhs(x, u0, p)
            k2 = rhs(axpy(x, half, k1), uh, p)
            k3 = rhs(axpy(x, half, k2), uh, p)
            k4 = rhs(axpy(x, h, k3), u1, p)
            return rk4_combine(x, h / 6.0, k1, k2, k3, k4)

    else:

        def rk4_step(x, u0, uh, u1, h, p):
            half = 0.5 * h
            trig = sincos(x[angle])
            k1 = rhs(x, trig, u0, p)
            k2 = rhs(axpy(x, half, k1), rotate(trig, half * k1[angle]), uh, p)
            k3 = rhs(axpy(x, half, k2), rotate(trig, half * k2[angle]), uh, p)
            k4 = rhs(axpy(x, h, k3), rotate(trig, h * k3[angle]), u1, p)
            return rk4_combine(x, h / 6.0, k1, k2, k3, k4)

    rk4_step.__qualname__ = f"rk4_step[{getattr(rhs, '__name__', 'rhs')}]"
    return jit(rk4_step)
