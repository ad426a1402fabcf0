"""Elementwise arithmetic on fixed-length tuples of floats, the state type of every RK4 step.

numba has no elementwise tuple arithmetic, and arrays would allocate inside
the hot loops. Each operation is a plain Python function (used as is with
``NUMBA_DISABLE_JIT=1`` and by the CUDA simulator) and an ``@overload`` that
generates the unrolled expression for the tuple's length at compile time,
for the CPU and the CUDA target alike. The generated expressions are written
in the same order as hand-unrolled code, so results are bit-identical to it.
"""

from numba.core import types
from numba.extending import overload


def axpy(x, a, k):
    """``x + a * k`` elementwise (``a`` a float)."""
    return tuple([xi + a * ki for xi, ki in zip(x, k)])


def rk4_combine(x, w, k1, k2, k3, k4):
    """``x + w * (k1 + 2 k2 + 2 k3 + k4)`` elementwise: the RK4 weighted stage sum."""
    return tuple([xi + w * (a + 2.0 * b + 2.0 * c + d) for xi, a, b, c, d in zip(x, k1, k2, k3, k4)])


def _unrolled(name, args, template, x_type):
    """Source-compiled ``name(*args)`` returning ``template`` at every index of tuple type ``x_type``.

    The template's constant ``two`` has the tuple's own float type, so a
    float32 state (the GPU's single-precision option) stays float32; in
    float64 it is the literal 2.0, bit for bit.
    """
    n = len(x_type)
    dtype = getattr(x_type, "dtype", None)
    two = dtype(2.0) if isinstance(dtype, types.Float) else 2.0
    body = ", ".join(template.format(i=i) for i in range(n))
    namespace: dict = {"two": two}
    exec(f"def {name}({', '.join(args)}):\n    return ({body},)\n", namespace)  # noqa: S102 - fixed templates
    return namespace[name]


@overload(axpy, inline="always")
def _axpy_overload(x, a, k):
    return _unrolled("axpy_impl", ("x", "a", "k"), "x[{i}] + a * k[{i}]", x)


@overload(rk4_combine, inline="always")
def _rk4_combine_overload(x, w, k1, k2, k3, k4):
    return _unrolled(
        "rk4_combine_impl",
        ("x", "w", "k1", "k2", "k3", "k4"),
        "x[{i}] + w * (k1[{i}] + two * k2[{i}] + two * k3[{i}] + k4[{i}])",
        x,
    )
