"""Branch-free sin and cos that LLVM can vectorise (numba cannot call SVML).

Range reduction ``x = k pi/2 + r`` is a two-piece Cody-Waite reduction:
``k * PIO2_HI`` is exact (33-bit piece) and so is ``x - k * PIO2_HI``, and
``PIO2_LO`` carries the rest of pi/2 to 3.5e-27. The kernels on
``|r| <= pi/4`` are fdlibm's ``__kernel_sin``/``__kernel_cos`` minimax
polynomials. The quadrant is selected with comparisons on the float
``k mod 4``, never a float-to-int conversion, so a NaN argument gives NaN and
no branch is taken per lane.

Accuracy (tests check 1e7 arguments up to |x| = 40 pi against a long-double
reference): within 1.6 ulp of the result where |sin x|, |cos x| > 1e-3, and
within 2 ulp + 1e-26 |x| next to the zeros, where fdlibm's third piece of pi/2
was dropped (6.5e-22 at |x| = 1e5); below 0.8 * 2**-52 in absolute terms
everywhere. sin(-0.0) is +0.0. That is far below
the rounding of the argument itself (ulp(x) / 2 = 4.4e-16 at x = 2 pi) and
1e6 times below RK4's truncation error at dt = 1 ms over 120 forcing periods
(``tests/test_batched.py``). The reduction stays exact for
``|x| <= 2**19 pi/2`` (about 8.2e5 rad); the pendulum angle is rewrapped to
(-pi, pi] every forcing period, so it stays within a few tens of radians even
while rotating.

:func:`rotate_sincos` gives the sine and cosine of ``x + d`` from those of
``x`` for a small increment ``d``: the RK4 step of the batched kernel calls
:func:`sincos_poly` once per step and rotates it to the stage angles
``theta + (h/2) k``, which differ from ``theta`` by at most ``h |theta'|``.
"""

import numba as nb
import numpy as np

_INV_PIO2 = 6.36619772367581382433e-01
_PIO2_HI = 1.57079632673412561417e00  # first 33 bits of pi/2: k * _PIO2_HI is exact for |k| < 2**20
_PIO2_LO = 6.07710050650619224932e-11  # pi/2 - _PIO2_HI, rounded to double (error < 7e-27)
_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10

_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11


# Both functions are compiled once, with the batched kernel's own flags, and
# inlined by LLVM (before it vectorises the lane loop), not by numba: numba's
# inlining copies a function's IR at every call site and made these two the
# larger part of the kernels' compile time (the scalar kernels inlined
# sincos_poly four times into a branch they never take). The flags make the
# inlined code the same, FMA contraction included, as numba's inlining gave;
# tests/test_lane_loop.py fails if the lane loop stops vectorising.
@nb.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def sincos_poly(x):
    """``(sin x, cos x)`` in float64, branch-free; see the module docstring for accuracy."""
    k = np.floor(x * _INV_PIO2 + 0.5)
    r = (x - k * _PIO2_HI) - k * _PIO2_LO  # the first difference is exact (Sterbenz)
    z = r * r
    s = r + (z * r) * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    c = (1.0 - 0.5 * z) + (z * z) * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    q = k - 4.0 * np.floor(0.25 * k)  # quadrant 0, 1, 2 or 3 (exact)
    sin_x = s if q == 0.0 else (c if q == 1.0 else (-s if q == 2.0 else -c))
    cos_x = c if q == 0.0 else (-s if q == 1.0 else (-c if q == 2.0 else s))
    return sin_x, cos_x


# Taylor coefficients of sin d and cos d (1/3!, 1/5!, ...; 1/2!, 1/4!, ...).
_R3, _R5, _R7, _R9 = -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0
_R2, _R4, _R6, _R8 = -0.5, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0

#: Largest increment [rad] for which :func:`rotate_sincos` is held to a few
#: ulp: the truncated series err by at most ``|d|**11 / 11! + |d|**10 / 10!``
#: (3e-17 at 0.1). An RK4 stage moves theta by at most ``h |theta'|``, which
#: stays below 0.1 rad at dt = 1 ms for |theta'| < 100 rad/s; the fastest
#: rotation of the paper's sweeps is 30 rad/s. Beyond it the error grows as
#: ``|d|**10 / 10!`` (3e-10 at 0.5 rad), still far below the error of an RK4
#: step that moves the angle that much.
ROTATE_MAX_STEP = 0.1


@nb.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def rotate_sincos(sincos, d):
    """``(sin(x + d), cos(x + d))`` from ``sincos = (sin x, cos x)``, for ``|d| <= ROTATE_MAX_STEP``.

    Angle addition with sin d and cos d from their Taylor series to the
    ninth and eighth power (branch-free, vectorisable, about a third of the
    operations of :func:`sincos_poly`). A NaN ``d`` gives NaN, an infinite one a
    non-finite pair (the kernel's end-of-period check marks such a lane diverged).
    """
    z = d * d
    sin_d = d + (d * z) * (_R3 + z * (_R5 + z * (_R7 + z * _R9)))
    cos_d = 1.0 + z * (_R2 + z * (_R4 + z * (_R6 + z * _R8)))
    s, c = sincos
    return s * cos_d + c * sin_d, c * cos_d - s * sin_d
