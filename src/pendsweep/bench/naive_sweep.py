"""The peer of ``pendsweep alpha``: a plain numba script a researcher would write.

Deliberately independent of pendsweep (run as a file, not a module: it never
imports the package): its own Eq. (11), its own RK4 with the signum held
over each 1 ms step, the paper's protocol (100 transient + 20 recorded
forcing periods per point) and max |theta| per point, printed at the end.

    python naive_sweep.py continue 0 45 0.5   # the canonical sweep: state carried, kick at rest
    python naive_sweep.py fresh 0 45 0.05     # every point from theta = 0.1 rad
"""

import math
import sys

import numba as nb
import numpy as np

m, l, b1, b2, b3, g = 0.27, 0.1955, 3.01411e-4, 4.5067e-5, 9.17e-7, 9.81
M, C, K, FE = 10.9, 20.0, 1910.0, 2.5


@nb.njit(cache=True)
def rhs(y, yd, th, thd, force, sg):
    s, c = math.sin(th), math.cos(th)
    fd = b1 * sg + b2 * thd + b3 * thd * thd * sg
    den = M + m * c * c
    common = force - C * yd - K * y - m * l * thd * thd * c + s * fd / l
    return yd, (common + m * g * s * s) / den, thd, -(s / l) * (common + (M + m) * g) / den - fd / (m * l * l)


@nb.njit(cache=True)
def point(alpha, y, yd, th, thd, periods, record):
    n = 400
    dt = 1.0 / (FE * n)
    biggest = 0.0
    for k in range(periods * n):
        t = k * dt
        sg = 1.0 if thd > 0 else (-1.0 if thd < 0 else 0.0)
        f0 = alpha * math.sin(2 * math.pi * FE * t)
        fh = alpha * math.sin(2 * math.pi * FE * (t + 0.5 * dt))
        f1 = alpha * math.sin(2 * math.pi * FE * (t + dt))
        a = rhs(y, yd, th, thd, f0, sg)
        b = rhs(y + 0.5 * dt * a[0], yd + 0.5 * dt * a[1], th + 0.5 * dt * a[2], thd + 0.5 * dt * a[3], fh, sg)
        c = rhs(y + 0.5 * dt * b[0], yd + 0.5 * dt * b[1], th + 0.5 * dt * b[2], thd + 0.5 * dt * b[3], fh, sg)
        d = rhs(y + dt * c[0], yd + dt * c[1], th + dt * c[2], thd + dt * c[3], f1, sg)
        y += dt / 6 * (a[0] + 2 * b[0] + 2 * c[0] + d[0])
        yd += dt / 6 * (a[1] + 2 * b[1] + 2 * c[1] + d[1])
        th += dt / 6 * (a[2] + 2 * b[2] + 2 * c[2] + d[2])
        thd += dt / 6 * (a[3] + 2 * b[3] + 2 * c[3] + d[3])
        if k >= (periods - record) * n:
            w = (th + math.pi) % (2 * math.pi) - math.pi
            biggest = max(biggest, abs(w))
    return y, yd, th, thd, biggest


if __name__ == "__main__":
    mode, lo, hi, step = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
    state = (0.0, 0.0, 0.1, 0.0)
    peaks = []
    for alpha in np.arange(lo, hi + 1e-9, step):
        if mode == "fresh":
            state = (0.0, 0.0, 0.1, 0.0)
        y, yd, th, thd, peak = point(alpha, *state, 120, 20)
        state = (y, yd, th + (0.1 if peak < 0.0013 else 0.0), thd)
        peaks.append(peak)
    print(len(peaks), "points, largest swing", max(peaks))
