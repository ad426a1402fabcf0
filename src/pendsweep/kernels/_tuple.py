"""Elementwise arithmetic on fixed-length tuples of floats, the state type of every RK4 step.

numba has no elementwise tuple arithmetic, and arrays would allocate inside
the hot loops. Each operation is a plain Python function (used as is with
``NUMBA_DISABLE_JIT=1`` and by the CUDA simulator) and an ``@overload`` that
generates the unrolled expression for the tuple's length at compile time,
for the CPU and the CUDA target alike. The generated expressions are written
in the same order as hand-unrolled code, so results are bit-identical to it.
"""

from numba.extending import overload


def axpy(x, a, k):
    """``x + a * k`` elementwise (``a`` a float)."""
    return tuple([xi + a * ki for xi, ki in zip(x, k)])


def rk4_combine(x, w, k1, k2, k3, k4):
    """``x + w * (k1 + 2 k2 + 2 k3 + k4)`` elementwise: the RK4 weighted stage sum."""
    return tuple([xi + w * (a + 2.0 * b + 2.0 * c + d) for xi, a, b, c, d in zip(x, k1, k2, k3, k4)])


def _unrolled(name, args, template, n):
    """Source-compiled function ``name(*args)`` returning ``template`` at indices 0..n-1 as a tuple."""
    body = ", ".join(template.format(i=i) for i in range(n))
    namespace: dict = {}
    exec(f"def {name}({', '.join(args)}):\n    return ({body},)\n", namespace)  # noqa: S102 - fixed templates
    return namespace[name]


@overload(axpy, inline="always")
def _axpy_overload(x, a, k):
    return _unrolled("axpy_impl", ("x", "a", "k"), "x[{i}] + a * k[{i}]", len(x))


@overload(rk4_combine, inline="always")
def _rk4_combine_overload(x, w, k1, k2, k3, k4):
    return _unrolled(
        "rk4_combine_impl",
        ("x", "w", "k1", "k2", "k3", "k4"),
        "x[{i}] + w * (k1[{i}] + 2.0 * k2[{i}] + 2.0 * k3[{i}] + k4[{i}])",
        len(x),
    )
