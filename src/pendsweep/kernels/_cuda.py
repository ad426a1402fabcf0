"""The emulated system's batched kernel on a CUDA GPU: one thread per parameter point.

Nothing here restates the physics. The right-hand sides of :mod:`._rhs` are
compiled as CUDA device functions by :func:`~._rhs.compile_physics`, the RK4
step by :func:`~._rk4.make_rk4_step`, and the step of Eq. (11)
(:func:`~._emulated.eq11_step`), its parameter tuple
(:func:`~._emulated.eq11_params`) and the per-period record bookkeeping of
:mod:`._records` are the CPU kernels' own plain functions recompiled for the
device with their callees rebound (:func:`retarget`). Only the loop that
arranges steps, forcing and records per thread is written here, and it
mirrors the CPU batched kernel (:mod:`._batched`): the vectorised formulation
of :func:`~._rhs.eq11_rhs` (reciprocals instead of divisions, which are slow
in float64 on a GPU), sin/cos from the device's libm, the running extremes of
a period kept in registers and written at the period's end, the forcing at
the half steps from the scalar kernel's table (:func:`~._emulated.forcing_table`
with unit amplitude, times ``alpha``), the same records and status codes.

float32: the float literals of every compiled function are retyped to
float32 (numba types a Python float literal as float64, which would promote
every expression), so the right-hand sides and the RK4 stages run in single
precision; the RK4 combination of the stages (whose ``2.0`` is inside the
generated tuple overload of :mod:`._tuple`) runs in float64 and the state is
rounded back to float32 after every step. Records and final states are
returned in float64 either way.

``numba.cuda`` is imported by :func:`import_cuda` only, never at module
import: without a GPU the rest of pendsweep must not depend on it.
"""

from __future__ import annotations

import functools
import math
import types

import numpy as np

from ._emulated import eq11_params, eq11_step
from ._layout import (
    REC_THETA_ABSMAX,
    REC_THETA_PEAK,
    REC_Y_ABSMAX,
    STATUS_DIVERGED,
    STATUS_OK,
    pendulum_params,
)
from ._records import TWO_PI, fold_extremes, record_close, wrap_angle, wrap_index
from ._rhs import compile_physics
from ._rk4 import make_rk4_step

#: Floating-point precisions of the device kernel.
PRECISIONS = {"float64": np.float64, "float32": np.float32}


def import_cuda():
    """``numba.cuda``, importable under numpy releases that dropped ``np.row_stack``.

    Some numba-cuda releases register ``np.row_stack`` (removed in numpy 2.5)
    while importing; it is the same function as ``np.vstack``, so the alias
    is restored before the import when numpy lacks it.
    """
    if not hasattr(np, "row_stack"):
        np.row_stack = np.vstack
    from numba import cuda

    _catch_core_typing_errors()
    return cuda


def _catch_core_typing_errors() -> None:
    """Let the out-of-tree numba-cuda lowering catch numba's own ``TypingError``.

    numba-cuda (0.30 tested) lowers a binary operator by first trying a
    static implementation and catching its own ``TypingError``; with numba
    0.68 the failed attempt raises ``numba.core.errors.TypingError``, a
    different class, so every ``0.5 * h`` aborted the compilation. The
    lowering module looks the name up when it handles the exception, so
    catching both restores the intended fallback. The numba-internal CUDA
    target has no such module and needs nothing.
    """
    try:
        from numba.core import errors as core_errors
        from numba.cuda import lowering
    except ImportError:
        return
    caught = getattr(lowering, "TypingError", None)
    if isinstance(caught, type) and caught is not core_errors.TypingError:
        lowering.TypingError = (caught, core_errors.TypingError)


def _float_constants_as(code: types.CodeType, real) -> types.CodeType:
    """``code`` with every float literal (also in nested code objects) replaced by ``real(literal)``."""
    consts = []
    for c in code.co_consts:
        if type(c) is float:
            c = real(c)
        elif isinstance(c, types.CodeType):
            c = _float_constants_as(c, real)
        consts.append(c)
    return code.replace(co_consts=tuple(consts))


def retarget(fn, jit, real=np.float64, **names):
    """Compile the plain function behind ``fn`` with ``jit``, the global ``names`` rebound.

    Parameters
    ----------
    fn : callable
        A plain function or a numba dispatcher (its ``py_func`` is used).
    jit : callable
        The target's decorator, e.g. ``cuda.jit(device=True)``.
    real : {numpy.float64, numpy.float32}
        Type given to the function's float literals (see the module docstring).
    **names
        Globals of ``fn`` to replace, typically its callees compiled for the target.
    """
    plain = getattr(fn, "py_func", fn)
    namespace = dict(plain.__globals__)
    namespace.update(names)
    code = plain.__code__ if real is np.float64 else _float_constants_as(plain.__code__, real)
    new = types.FunctionType(code, namespace, plain.__name__, plain.__defaults__, plain.__closure__)
    new.__qualname__ = plain.__qualname__
    new.__doc__ = plain.__doc__
    return jit(new)


def _libm_sincos(x):
    """``(sin x, cos x)`` from the device's libm (replaces the CPU's vectorisable polynomial)."""
    return math.sin(x), math.cos(x)


#: Rebound per compilation by :func:`emulated_kernel` (see :func:`_emulated_periods_thread`).
cuda = None
REAL = np.float64
SGN_PER_STAGE = False


def _emulated_periods_thread(state, params, alpha, dt, steps, table_start, table, transient_periods, out, status, done):
    """The body of one thread of :func:`emulated_kernel` (plain Python, compiled with its callees rebound)."""
    i = cuda.grid(1)
    if i >= state.shape[0]:
        return
    n = steps[i]
    t0 = table_start[i]
    a = alpha[i]
    h = dt[i]
    q = eq11_params(params[i], SGN_PER_STAGE, True)
    y, yd, th, thd = state[i, 0], state[i, 1], state[i, 2], state[i, 3]
    # Running extremes of the current period, opened with its first sample.
    absmax, peak, yabs = fold_extremes(0.0, 0.0, 0.0, y, th) if math.isfinite(th) else (0.0, 0.0, 0.0)
    total = transient_periods + out.shape[1]
    code = STATUS_OK
    periods = total
    for period in range(total):
        for j in range(n):
            k = t0 + 2 * j
            y1, yd1, th1, thd1 = eq11_step((y, yd, th, thd), a * table[k], a * table[k + 1], a * table[k + 2], h, q)
            # The carried state keeps the kernel's precision (see the module docstring).
            y, yd, th, thd = REAL(y1), REAL(yd1), REAL(th1), REAL(thd1)
            # A diverging point's records become NaN at the period's end; skipping its
            # non-finite samples keeps wrap_index from converting NaN (an error in the simulator).
            if math.isfinite(th):
                absmax, peak, yabs = fold_extremes(absmax, peak, yabs, y, th)
        r = period - transient_periods
        if not (math.isfinite(y) and math.isfinite(yd) and math.isfinite(th) and math.isfinite(thd)):
            if r >= 0:
                for c in range(out.shape[2]):
                    out[i, r, c] = math.nan
            code = STATUS_DIVERGED
            periods = period
            break
        # Net passes over the top in this period; rewrapping keeps theta bounded.
        turns = wrap_index(th)
        th = REAL(th - TWO_PI * turns)
        if r >= 0:
            row = out[i, r]
            row[REC_THETA_PEAK] = peak
            row[REC_THETA_ABSMAX] = absmax
            row[REC_Y_ABSMAX] = yabs
            record_close(row, y, yd, th, thd, turns)
        absmax, peak, yabs = fold_extremes(0.0, 0.0, 0.0, y, th)
    state[i, 0] = y
    state[i, 1] = yd
    state[i, 2] = th
    state[i, 3] = thd
    status[i] = code
    done[i] = periods


@functools.cache
def emulated_kernel(precision: str = "float64", sgn_per_stage: bool = False):
    """The CUDA kernel (a ``cuda.jit`` dispatcher) of :func:`emulated_kernel_function`."""
    return import_cuda().jit(emulated_kernel_function(precision, sgn_per_stage))


def emulated_kernel_function(precision: str = "float64", sgn_per_stage: bool = False):
    """The kernel integrating integrating whole forcing periods of many points, one thread per point.

    Parameters
    ----------
    precision : {"float64", "float32"}
        Arithmetic of the right-hand sides and the carried state.
    sgn_per_stage : bool
        Evaluate sgn(thetadot) at every RK4 stage instead of once per step.

    Returns
    -------
    function
        The plain thread body with its callees compiled as CUDA device
        functions, to be compiled by ``cuda.jit`` (or ``cuda.compile_ptx``);
        as a kernel it is launched as ``kernel[blocks, threads](state, params, alpha, dt, steps, table_start,
        table, transient_periods, out, status, done)``, for ``n`` points:

        - ``state`` real[n, 4]: ``(y [m], ydot [m/s], theta [rad], thetadot
          [rad/s])`` at forcing phase 0, overwritten with the final state
          (theta wrapped; a diverged point keeps its non-finite state);
        - ``params`` real[n, N_PARAMS]: ``ModelParams.kernel_array`` rows;
        - ``alpha`` real[n] forcing amplitude [N], ``dt`` real[n] step [s],
          ``steps`` int64[n] RK4 steps per forcing period;
        - ``table`` real[:]: concatenated unit forcing tables
          ``forcing_table(1.0, steps)``, point ``i``'s starting at ``table_start[i]``;
        - ``transient_periods`` int: periods integrated before recording;
        - ``out`` float64[n, record_periods, N_RECORD_COLUMNS]: one row per
          recorded period (rows after a divergence are left untouched);
        - ``status`` int64[n]: ``STATUS_OK`` or ``STATUS_DIVERGED``;
        - ``done`` int64[n]: periods completed, transient included, before any divergence.

        The point with index ``i`` is integrated exactly as
        ``batched_periods`` integrates it in a chunk of points sharing its
        steps per period, except that sin/cos come from the device's libm
        at every stage (``batched_periods`` rotates one ``sincos_poly`` per
        step to its stages).
    """
    if precision not in PRECISIONS:
        raise ValueError(f"precision = {precision!r}; choose one of {', '.join(PRECISIONS)}")
    cuda_module = import_cuda()
    real = PRECISIONS[precision]
    device = cuda_module.jit(device=True)

    def jit(fn):
        """The device decorator, with ``fn``'s float literals of the kernel's precision."""
        return retarget(fn, device, real)

    physics = compile_physics(jit, overrides={"sincos_poly": jit(_libm_sincos)})
    rk4 = make_rk4_step(physics.eq11_rhs, jit)
    wrap_index_d = jit(wrap_index)
    # The device keeps the integer turns (its conversions are cheap; numpy's ceil is a CPU helper).
    wrap_angle_d = retarget(wrap_angle, device, real, wrap_turns=wrap_index_d)
    return retarget(
        _emulated_periods_thread,
        lambda fn: fn,
        cuda=cuda_module,
        REAL=real,
        SGN_PER_STAGE=bool(sgn_per_stage),
        eq11_params=retarget(eq11_params, device, real, pendulum_params=jit(pendulum_params)),
        eq11_step=retarget(eq11_step, device, real, signum=physics.signum, eq11_rk4=rk4),
        fold_extremes=retarget(fold_extremes, device, real, wrap_angle=wrap_angle_d),
        record_close=retarget(record_close, device, real, wrap_angle=wrap_angle_d),
        wrap_index=wrap_index_d,
    )
