"""Many parameter points integrated in lockstep, vectorised across points.

The scalar kernel (:func:`pendsweep.kernels.emulated_periods`) spends its
time in libm ``sin``/``cos``, which LLVM cannot vectorise. Here the state of
a chunk of points (lanes) lives in structure-of-arrays form and the
innermost loop runs over lanes, so that LLVM turns one RK4 step of the whole
chunk into packed AVX2 or AVX-512 code, two vector iterations interleaved
(:mod:`pendsweep.kernels._vector_width`), no scalar double arithmetic in the loop for
either (``make bench`` and the tests inspect both builds); ``sin``/``cos`` come from the branch-free
:func:`~pendsweep.kernels._sincos.sincos_poly`, once per step, rotated to
the later stages by :func:`~pendsweep.kernels._sincos.rotate_sincos`. The forcing at the stage
times is read from the scalar kernel's half-step table of the lane's own
steps per period, so lanes with different ``fe`` share a chunk and **a
lane's result never depends on the other lanes of its chunk** (which makes
a resumed sweep bit-identical whatever was done before; chunks are padded
to whole vector groups so that every lane runs the same FMA-contracted vector
code). A lane that has
finished or diverged is frozen by a select. Period ends are rare events
handled by a scalar pass that fills the same records as the scalar kernel.

Twin lanes: a lane with a ``partner`` follows it at a small distance for the
two-trajectory Lyapunov estimate of :mod:`pendsweep.analysis.classify`. At every
period end the twin's separation from its partner (normalised section
coordinates) gives one log-stretch sample, and the twin is pulled back to
distance ``d0`` along the separation (Benettin), all inside the kernel.

Chunks run in parallel on Python threads (the chunk kernel releases the
GIL), as many as numba's thread count for the calling thread: a ``prange``
would cost numba's parallel compilation (a quarter of the batched kernel's
compile time, on every cold start) for a loop that only hands out chunks.
"""

import math
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numba as nb
import numpy as np

from ._emulated import forcing_table
from ._layout import (
    N_PARAMS,
    P_B1,
    P_B2,
    P_B3,
    P_C,
    P_G,
    P_K,
    P_K3,
    P_L,
    P_M,
    P_M_PEND,
    REC_THETA_ABSMAX,
    REC_THETA_PEAK,
    REC_Y_ABSMAX,
    STATUS_DIVERGED,
    STATUS_OK,
)
from ._records import TWO_PI, fold_extremes, record_close, wrap_angle, wrap_index
from ._rhs import signum
from ._steps import eq11_rotating_rk4

# Rows of a chunk's per-lane constant table: the parameter vector, then these.
_ALPHA, _TABLE, _STEPS, _DT, _INV_L, _INV_M = range(N_PARAMS, N_PARAMS + 6)
_N_CONST = N_PARAMS + 6

#: Lanes per vector group: chunks are padded with idle lanes to a multiple of
#: this (8 float64 lanes fill an AVX-512 register; a multiple of AVX2's 4).
LANE_GROUP = 16


class Lanes(NamedTuple):
    """Per-lane schedule of :func:`batched_periods` (arrays of length n).

    Attributes
    ----------
    transient : int64[n]
        Periods integrated before the lane's first record row.
    total : int64[n]
        Periods integrated in all (transient included; at most
        ``transient + out.shape[1]``).
    partner : int64[n]
        -1, or the index of the lane this one is a twin of; the partner must
        lie in the same chunk at a smaller index and share ``steps``.
    scales : float64[4, n]
        Divisors making a twin's section separation dimensionless
        (``pendsweep.analysis.sections.section_scales``).
    d0 : float
        Twin separation after each renormalisation [normalised].
    rest : float
        A twin stops (its samples end) once its partner's period swing,
        max |theta|, falls below this [rad]: at rest the separation means nothing.
    """

    transient: np.ndarray
    total: np.ndarray
    partner: np.ndarray
    scales: np.ndarray
    d0: float
    rest: float


@nb.njit(cache=True, nogil=True, inline="always")
def twin_separation(ref, twin, scales):
    """Section separation of ``twin`` from ``ref`` (4-tuples): ``(full, distance)``.

    ``full`` is the separation in state units with the angle difference
    wrapped to (-pi, pi]; ``distance`` its norm in the normalised units of ``scales``.
    """
    full = (twin[0] - ref[0], twin[1] - ref[1], wrap_angle(twin[2] - ref[2]), twin[3] - ref[3])
    u0, u1, u2, u3 = full[0] / scales[0], full[1] / scales[1], full[2] / scales[2], full[3] / scales[3]
    return full, math.sqrt(u0 * u0 + u1 * u1 + u2 * u2 + u3 * u3)


@nb.njit(cache=True, nogil=True, inline="always")
def _gather_forcing(forcing, const, tables, k):
    """Each lane's unit forcing sines at the stage times of step ``k``, from its own table."""
    for i in range(forcing.shape[1]):
        n = int(const[_STEPS, i])
        j = int(const[_TABLE, i]) + 2 * (k % n)
        forcing[0, i] = tables[j]
        forcing[1, i] = tables[j + 1]
        forcing[2, i] = tables[j + 2]


# error_model="numpy": no ZeroDivisionError branch (every denominator is > 0),
# which would keep LLVM from vectorising the lane loop. One call runs every
# step up to the next period end, so the lane loop's runtime alias checks and
# the call itself are paid once a period, not once a step (a fifth of the
# time of a 64-lane chunk). The lane loop writes only six arrays: more would
# exceed LLVM's budget of runtime alias checks. It is written here rather than
# in a helper inlined by numba: numba copies an inlined function's whole IR,
# once per level of inlining, which made the lane loop's helper cost seconds
# of compile time. FMA contraction (about a third of the kernel's
# time, with the short range reduction of sincos_poly) is safe only because
# every chunk is padded to a whole number of vector groups (LANE_GROUP): LLVM
# contracts the vector body and its scalar remainder loop differently, and a
# lane that ran in the remainder would differ in its last bits (on a chaotic
# orbit, in its whole trajectory) from the same lane in the vector body.
@nb.njit(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
def _advance_chunk(y, yd, th, thd, peak, yabs, live, const, forcing, tables, uniform, k_start, k_stop, sgn_per_stage):
    """Steps ``k_start`` to ``k_stop - 1`` of every live lane (no lane's period ends before ``k_stop``).

    ``y, yd, th, thd`` are the state, ``peak`` the signed wrapped theta of
    largest modulus and ``yabs`` the max |y| of the current period (all
    float64[n], updated in place); ``live`` is 1.0 for lanes still being
    integrated; ``const`` is float64[_N_CONST, n]; ``forcing`` (float64[3, n])
    receives each lane's unit forcing sines at the stage times of the step;
    ``tables`` are the chunk's unit forcing tables (a uniform chunk uses the
    first, of ``const[_STEPS, 0]`` steps).
    """
    steps = int(const[_STEPS, 0])
    for k in range(k_start, k_stop):
        if uniform:  # one table: a broadcast (the lane loop reads forcing either way, one copy of it)
            j = 2 * (k % steps)
            forcing[0, :] = tables[j]
            forcing[1, :] = tables[j + 1]
            forcing[2, :] = tables[j + 2]
        else:
            _gather_forcing(forcing, const, tables, k)
        for i in range(y.shape[0]):  # the lane loop, vectorised
            s0, s1, s2 = forcing[0, i], forcing[1, i], forcing[2, i]
            a = const[_ALPHA, i]
            y0, yd0, th0, thd0, pk0, ya0 = y[i], yd[i], th[i], thd[i], peak[i], yabs[i]
            q = (
                const[P_M_PEND, i], const[P_L, i], const[P_B1, i], const[P_B2, i], const[P_B3, i],
                const[P_G, i], const[P_M, i], const[P_C, i], const[P_K, i], const[P_K3, i],
                sgn_per_stage, True, const[_INV_L, i], const[_INV_M, i],
            )  # fmt: skip
            held = signum(thd0)  # sgn(theta') held over the step, as in eq11_step
            y1, yd1, th1, thd1 = eq11_rotating_rk4(
                (y0, yd0, th0, thd0), (a * s0, held), (a * s1, held), (a * s2, held), const[_DT, i], q
            )
            _, pk1, ya1 = fold_extremes(abs(pk0), pk0, ya0, y1, th1)
            on = live[i] != 0.0
            y[i] = y1 if on else y0
            yd[i] = yd1 if on else yd0
            th[i] = th1 if on else th0
            thd[i] = thd1 if on else thd0
            peak[i] = pk1 if on else pk0
            yabs[i] = ya1 if on else ya0


@nb.njit(cache=True, nogil=True, inline="always")
def _any_live(live):
    """Whether any lane is still integrated."""
    for i in range(live.shape[0]):
        if live[i] != 0.0:
            return True
    return False


@nb.njit(cache=True, nogil=True)
def _chunk_constants(const, p, alpha, fe, steps, lo, hi):
    """Fill ``const`` (float64[_N_CONST, width]) for lanes ``lo:hi``; return their concatenated unit forcing tables.

    Lanes past ``hi - lo`` (the idle padding) get the first lane's constants.
    Every copy is an explicit loop: numba compiles an array-to-slice
    assignment with a formatted shape-mismatch error, seconds of compile time
    per kind of slice.
    """
    n = hi - lo
    size = 0
    for i in range(lo, hi):
        if i == lo or steps[i] != steps[i - 1]:
            size += 2 * steps[i] + 1
    tables = np.empty(size)
    offset = -1
    for i in range(n):
        g = lo + i
        if i == 0 or steps[g] != steps[g - 1]:  # lanes sorted by steps share one table
            offset = offset + 2 * steps[g - 1] + 1 if i > 0 else 0
            table = forcing_table(1.0, steps[g])
            for k in range(table.shape[0]):
                tables[offset + k] = table[k]
        for row in range(N_PARAMS):
            const[row, i] = p[row, g]
        const[_ALPHA, i] = alpha[g]
        const[_TABLE, i] = offset
        const[_STEPS, i] = steps[g]
        const[_DT, i] = 1.0 / (fe[g] * steps[g])
        const[_INV_L, i] = 1.0 / p[P_L, g]
        const[_INV_M, i] = 1.0 / p[P_M_PEND, g]
    for i in range(n, const.shape[1]):
        for row in range(_N_CONST):
            const[row, i] = const[row, 0]
    return tables


@nb.njit(cache=True, nogil=True)
def _close_period(i, y, yd, th, thd, peak, yabs, live, swing, period, lanes, lo, out, status, done, stretch):
    """Period end of lane ``i`` (chunk-local; ``lo`` is the chunk's first global index)."""
    kp = period[i]
    r = kp - lanes.transient[lo + i]
    if not (math.isfinite(y[i]) and math.isfinite(yd[i]) and math.isfinite(th[i]) and math.isfinite(thd[i])):
        if 0 <= r < out.shape[1]:
            out[i, r, :] = np.nan
        status[i] = STATUS_DIVERGED
        done[i] = kp
        live[i] = 0.0
        return
    # Net passes over the top in this period; rewrapping keeps theta bounded.
    turns = wrap_index(th[i])
    th[i] -= TWO_PI * turns
    swing[i] = abs(peak[i])
    if 0 <= r < out.shape[1]:  # the schedule keeps r below out.shape[1]; never write past it
        row = out[i, r]
        row[REC_THETA_PEAK] = peak[i]
        row[REC_THETA_ABSMAX] = swing[i]
        row[REC_Y_ABSMAX] = yabs[i]
        record_close(row, y[i], yd[i], th[i], thd[i], turns)
    period[i] = kp + 1
    if kp + 1 == lanes.total[lo + i]:
        live[i] = 0.0
    _, peak[i], yabs[i] = fold_extremes(0.0, 0.0, 0.0, y[i], th[i])
    if lanes.partner[lo + i] >= 0:  # a twin: one Lyapunov sample, then back to distance d0
        ref = lanes.partner[lo + i] - lo
        s = lanes.scales[:, lo + i]
        full, distance = twin_separation((y[ref], yd[ref], th[ref], thd[ref]), (y[i], yd[i], th[i], thd[i]), s)
        if swing[ref] < lanes.rest or not (math.isfinite(distance) and distance > 0):
            live[i] = 0.0
            return
        if kp < stretch.shape[1]:
            stretch[i, kp] = math.log(distance / lanes.d0)
        g = lanes.d0 / distance
        y[i], yd[i] = y[ref] + full[0] * g, yd[ref] + full[1] * g
        th[i], thd[i] = th[ref] + full[2] * g, thd[ref] + full[3] * g


@nb.njit(cache=True, nogil=True)
def _integrate_chunk(state, p, alpha, fe, steps, lanes, lo, hi, sgn_per_stage, out, status, done, stretch):
    """Integrate lanes ``lo:hi`` (all arrays whole, ``out`` to ``stretch`` the chunk's slices); see :func:`batched_periods`."""
    n = hi - lo
    # Lanes n..width-1 are idle padding (live = 0, lane 0's constants), so the
    # vectorised step never falls back to its scalar remainder loop.
    width = -(-n // LANE_GROUP) * LANE_GROUP
    y, yd, th, thd = np.zeros(width), np.zeros(width), np.zeros(width), np.zeros(width)
    peak, yabs, live = np.zeros(width), np.zeros(width), np.zeros(width)
    swing = np.zeros(n)
    period = np.zeros(n, dtype=np.int64)
    period_end = np.empty(n, dtype=np.int64)  # step count at the end of each lane's current period
    const = np.empty((_N_CONST, width))
    tables = _chunk_constants(const, p, alpha, fe, steps, lo, hi)
    # max_steps and k start as np.int64(0), not the literal 0: numba would also compile _advance_chunk for a
    # literal first step (typing sees the loop's first value before it unifies the type), seconds of compile.
    max_steps = np.int64(0)
    for i in range(n):
        y[i], yd[i], th[i], thd[i] = state[0, lo + i], state[1, lo + i], state[2, lo + i], state[3, lo + i]
        period_end[i] = steps[lo + i]
        _, peak[i], yabs[i] = fold_extremes(0.0, 0.0, 0.0, y[i], th[i])  # the opening sample
        status[i] = STATUS_OK
        done[i] = lanes.total[lo + i]
        max_steps = max(max_steps, lanes.total[lo + i] * steps[lo + i])
        live[i] = 1.0 if lanes.total[lo + i] > 0 else 0.0
    uniform = n > 0
    for i in range(lo + 1, hi):
        uniform = uniform and steps[i] == steps[lo]
    forcing = np.zeros((3, width))  # every lane's unit forcing at the current step's stage times
    k = np.int64(0)
    while k < max_steps:
        stop = max_steps
        for i in range(n):  # a loop, not period_end.min(): numba's array reductions take seconds to compile
            stop = min(stop, period_end[i])
        _advance_chunk(y, yd, th, thd, peak, yabs, live, const, forcing, tables, uniform, k, stop, sgn_per_stage)
        k = stop
        for i in range(n):
            if period_end[i] == k:
                period_end[i] += steps[lo + i]
                if live[i] != 0.0:
                    _close_period(
                        i, y, yd, th, thd, peak, yabs, live, swing, period, lanes, lo, out, status, done, stretch
                    )
        if not _any_live(live):  # lanes stop only at period ends
            break
    for i in range(n):
        state[0, lo + i], state[1, lo + i], state[2, lo + i], state[3, lo + i] = y[i], yd[i], th[i], thd[i]


def batched_periods(state, p, alpha, fe, steps, lanes, sgn_per_stage, bounds, out, status, done, stretch):
    """Integrate whole forcing periods of many lanes and fill per-period records.

    Lane ``i`` is integrated as ``emulated_periods`` would with
    ``state[:, i]``, ``p[:, i]``, ``alpha[i]``, ``fe[i]``, ``steps[i]`` and
    ``lanes.transient[i]``, except that sin/cos come from
    :func:`sincos_poly` (<= 0.8 * 2**-52 absolute) once per step, rotated to the
    stages (:func:`rotate_sincos`, a few ulp), divisions become reciprocals
    and products and sums contract to FMA (tests bound the departure from the
    exact kernel at 1e-6 of RK4's own truncation error over 120 periods).

    Parameters
    ----------
    state : float64[4, n]
        ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])`` per lane at
        forcing phase 0 (structure of arrays); overwritten with the final
        states (theta wrapped; a diverged lane keeps its non-finite state).
    p : float64[N_PARAMS, n]
        Parameter vectors (``ModelParams.kernel_array``) as columns.
    alpha, fe : float64[n]
        Forcing amplitude [N] and frequency [Hz] per lane.
    steps : int64[n]
        RK4 steps per forcing period per lane; ``dt = 1 / (fe * steps)``.
        Within a chunk, lanes sorted by ``steps`` share one forcing table.
    lanes : Lanes
        Per-lane schedule and twins.
    sgn_per_stage : bool
        Evaluate sgn(thetadot) at every RK4 stage instead of once per step.
    bounds : int64[n_chunks + 1]
        Chunk ``c`` holds lanes ``bounds[c]:bounds[c + 1]``, integrated in
        lockstep by one thread; chunks run in parallel.
    out : float64[n, n_record, N_RECORD_COLUMNS]
        Filled with one row per recorded period (see ``_layout``); rows after
        a divergence or past a lane's total are left untouched.
    status : int64[n]
        ``STATUS_OK`` or ``STATUS_DIVERGED`` per lane.
    done : int64[n]
        Periods completed (transient included) before any divergence.
    stretch : float64[n, n_stretch]
        Twins' per-period log-stretch samples ``log(distance / d0)``;
        untouched after a twin stops (callers fill it with NaN).
    """

    def integrate(c):
        lo, hi = bounds[c], bounds[c + 1]
        _integrate_chunk(
            state, p, alpha, fe, steps, lanes, lo, hi, sgn_per_stage, out[lo:hi], status[lo:hi], done[lo:hi],
            stretch[lo:hi],
        )  # fmt: skip

    chunks = range(bounds.shape[0] - 1)
    threads = min(nb.get_num_threads(), len(chunks))
    if threads <= 1:
        for c in chunks:
            integrate(c)
        return
    with ThreadPoolExecutor(threads) as pool:
        for _ in pool.map(integrate, chunks):  # re-raises a chunk's exception
            pass
