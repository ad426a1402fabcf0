"""The paper's appendix procedure for pendulum damping from free swings (Fig. 2).

The swing obeys, per unit moment of inertia I about the pivot,

    theta'' + beta1 sgn(theta') + beta2 theta' + beta3 theta'^2 sgn(theta') + (g/L) sin theta = 0,

with ``beta_i = b_i / I`` and the equivalent length ``L = I / (m d)`` of a
physical pendulum (``I = m l^2`` for the paper's point mass). Averaging over a
half cycle of amplitude A and frequency omega gives the decrement

    dA = 2 beta1 / omega^2 + (pi beta2 / (2 omega)) A + (4/3) beta3 A^2.

1. ``beta2`` (and a first ``beta1``) from the small-angle half of the swing, by a
   linear fit of the decrement against amplitude;
2. ``beta1`` from the large-angle half, by an exponential fit of the envelope
   ``A(t) = (A0 + c) exp(-beta2 t / 2) - c`` (``beta2`` from step 1), which
   solves the averaged ``dA/dt = -beta2 A / 2 - 2 beta1 / (pi omega)``;
3. ``beta1, beta2, beta3`` and ``L`` updated jointly by the sensitivity-matrix
   method (Friswell & Mottershead 1995, ch. 6): the measured turning points
   (amplitudes and times, so the period fixes L) against those of the
   simulated nonlinear swing; the sensitivity matrix is by finite differences
   and each update is a regularised least-squares step. The zero offset and
   the velocity at the start are updated with them. The simulation starts at
   the second turning point (``skip = 1``): the velocity is zero there, so the
   unknown release velocity drops out, and the first half swing, which the
   releasing hand may still touch, is left out.

Note: the paper's appendix says "b2 from a linear fit ... b1 from an
exponential" while its Eq. (2) makes b1 Coulomb and b2 viscous; a linear
decay is Coulomb's signature and an exponential one viscous, so step 1's
slope is the viscous term and step 2's offset the Coulomb term, as above.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ...errors import ConfigError
from ...kernels import pendulum_trace
from ...model.params import kernel_vector
from ..records import Record
from .replay.whole import MAX_STEP
from .signals import noise_std, smoothed
from .signatures import extrema

#: Names of the physical parameters (per unit inertia) and nuisance parameters.
PHYSICS = ("beta1", "beta2", "beta3", "L")
NUISANCE = ("theta_offset",)
MAX_ITERATIONS = 40


@dataclass
class DampingFit:
    """Result of the three-step procedure on one record.

    ``physics`` maps beta1 [1/s^2], beta2 [1/s], beta3 [-] and L [m];
    ``stages`` the values after steps 1 and 2; ``envelope_error`` the maximum
    relative error of the simulated turning-point amplitudes.
    """

    physics: dict[str, float]
    stderr: dict[str, float]
    nuisance: dict[str, float]
    stages: dict[str, dict[str, float]]
    envelope_error: float
    iterations: int
    measured: np.ndarray = field(repr=False)
    simulated: np.ndarray = field(repr=False)

    def model_params(self, m: float) -> dict[str, float]:
        """``l = L`` and ``b_i = beta_i m L^2`` for a point mass ``m`` [kg]."""
        inertia = m * self.physics["L"] ** 2
        return {
            "m": m,
            "l": self.physics["L"],
            "b1": self.physics["beta1"] * inertia,
            "b2": self.physics["beta2"] * inertia,
            "b3": self.physics["beta3"] * inertia,
        }


class _Swing:
    """Measured turning points of a free swing and their simulation."""

    def __init__(self, record: Record, g: float, skip: int = 1):
        if record.kind != "free_decay":
            raise ConfigError(f"{record.name}: fit-damping needs a free_decay record, got {record.kind!r}")
        self.g = g
        self.dt = record.dt
        self.substeps = max(1, math.ceil(self.dt / MAX_STEP - 1e-9))
        theta = record.channel("theta")
        step = noise_std(theta) * math.sqrt(12.0)
        # Ignore turning points within a few encoder steps of rest.
        self.min_amp = max(10.0 * step, 0.01)
        ex = extrema(record.t - record.t[0], theta)
        mids = 0.5 * (ex.theta.to_numpy()[:-1] + ex.theta.to_numpy()[1:])
        self.offset0 = float(np.median(mids)) if len(mids) else 0.0
        ex = ex[np.abs(ex.theta - self.offset0) > self.min_amp].reset_index(drop=True)
        if len(ex) < skip + 6:
            raise ConfigError(
                f"{record.name}: {len(ex)} turning points above {self.min_amp:.3g} rad; "
                f"the fit needs at least {skip + 6} (skip = {skip})"
            )
        # Start at turning point `skip`, where the velocity is zero: the release
        # velocity drops out and the hand's last touch is left behind.
        i0 = int(round(ex.t.iloc[skip] / self.dt))
        self.theta = theta[i0:]
        self.n = len(self.theta)
        self.ex = ex.iloc[skip + 1 :].reset_index(drop=True)
        self.ex["t"] -= i0 * self.dt
        self.k = len(self.ex)
        th, thd = smoothed(self.theta, self.dt)
        self.theta_init0, self.thetadot_init0 = float(th[0]), float(thd[0])
        # Measurement scatter of turning points: encoder step and one sample.
        self.sigma_a = max(step, 1e-4)
        self.sigma_t = self.dt

    def amplitudes(self, offset: float) -> np.ndarray:
        return np.abs(self.ex.theta.to_numpy() - offset)

    def simulate(self, q: dict[str, float], n: int | None = None) -> np.ndarray:
        """Simulated angle (offset included) at the record's samples."""
        L = q["L"]
        # Unit mass: the decay depends on the damping only through beta_i = b_i / (m l^2).
        p = kernel_vector(dict(m=1.0, l=L, b1=q["beta1"] * L * L, b2=q["beta2"] * L * L, b3=q["beta3"] * L * L,
                               g=self.g, M=1.0, C=0.0, K=1.0, k3=0.0))  # fmt: skip
        out = np.empty((n or self.n, 2))
        pendulum_trace(
            np.array([q["theta_init"] - q["theta_offset"], q["thetadot_init"]]), p, self.dt, self.substeps, out
        )
        return out[:, 0] + q["theta_offset"]

    def turning_points(self, q: dict[str, float]) -> np.ndarray:
        """Simulated ``(time, amplitude)`` of the first ``k`` turning points, shape (k, 2)."""
        theta = self.simulate(q, int(self.n * 1.5))
        if not np.all(np.isfinite(theta)):
            return np.full((self.k, 2), np.nan)
        t = np.arange(len(theta)) * self.dt
        ex = extrema(t, theta - q["theta_offset"], self.min_amp)
        # The start is itself a turning point; compare from the next one on.
        ex = ex[ex.t > 0.5 * self.ex.t.iloc[0]]
        out = np.full((self.k, 2), np.nan)
        m = min(len(ex), self.k)
        out[:m, 0] = ex.t.to_numpy()[:m]
        out[:m, 1] = np.abs(ex.theta.to_numpy()[:m])
        return out

    def residual(self, q: dict[str, float]) -> np.ndarray:
        sim = self.turning_points(q)
        meas_a = self.amplitudes(q["theta_offset"])
        r = np.concatenate([(sim[:, 1] - meas_a) / self.sigma_a, (sim[:, 0] - self.ex.t.to_numpy()) / self.sigma_t])
        # A missing turning point (swing died out too early) costs its full amplitude.
        return np.where(np.isfinite(r), r, np.concatenate([meas_a / self.sigma_a, np.full(self.k, 0.1 / self.sigma_t)]))

    def envelope_error(self, q: dict[str, float]) -> float:
        sim = self.turning_points(q)[:, 1]
        meas = self.amplitudes(q["theta_offset"])
        with np.errstate(invalid="ignore"):
            rel = np.abs(sim - meas) / meas
        return float(np.max(np.where(np.isfinite(rel), rel, 1.0)))


def _initial_estimates(sw: _Swing) -> dict[str, dict[str, float]]:
    """Steps 1 and 2, and L from the small-amplitude period."""
    a = sw.amplitudes(sw.offset0)
    t = sw.ex.t.to_numpy()
    half = np.diff(t)
    amp = 0.5 * (a[:-1] + a[1:])
    dec = a[:-1] - a[1:]
    small = amp <= np.median(amp)
    # Period of the smaller swings, corrected to zero amplitude: T = T0 (1 + A^2/16).
    omega0 = float(np.mean(math.pi / half[small] * (1.0 + amp[small] ** 2 / 16.0)))
    L = sw.g / omega0**2
    c1, c0 = np.polyfit(amp[small], dec[small], 1)
    beta2 = max(float(c1) * 2.0 * omega0 / math.pi, 0.0)
    beta1_lin = max(float(c0) * omega0**2 / 2.0, 0.0)
    step1 = {"beta1": beta1_lin, "beta2": beta2, "beta3": 0.0, "L": L}
    large = a >= np.median(a)
    lam = 0.5 * beta2
    tl, al = t[large], a[large]

    def env(x):
        a0, c = x
        if lam > 0:
            return (a0 + c) * np.exp(-lam * (tl - tl[0])) - c - al
        return a0 - c * (tl - tl[0]) - al

    sol = least_squares(env, [al[0], 0.1], method="lm")
    c = float(sol.x[1])
    # c = kappa / lambda with kappa = 2 beta1 / (pi omega); linear decay when beta2 = 0.
    kappa = c * lam if lam > 0 else c
    beta1 = max(kappa * math.pi * omega0 / 2.0, 0.0)
    step2 = dict(step1, beta1=beta1)
    return {"step1_small_angle_linear": step1, "step2_large_angle_exponential": step2}


def _update(sw: _Swing, q: dict[str, float], free: tuple[str, ...], scales: dict[str, float]) -> tuple[dict, dict, int]:
    """Sensitivity-matrix updating of the ``free`` parameters of ``q``.

    Each iteration builds S = dz/dq by forward differences and takes the
    regularised step ``dq = (S^T W S + mu D)^-1 S^T W (z_m - z)`` (W = 1/sigma^2
    already in the residual), with mu adapted as in Levenberg-Marquardt and
    the damping coefficients kept non-negative.
    """
    q = dict(q)
    x = np.array([q[n] for n in free])
    sc = np.array([scales[n] for n in free])
    nonneg = np.array([n.startswith("beta") for n in free])

    def res(xv):
        return sw.residual(dict(q, **dict(zip(free, xv))))

    r = res(x)
    cost = float(r @ r)
    mu = 1e-3
    it = 0
    for it in range(1, MAX_ITERATIONS + 1):  # noqa: B007 - the iterations used are returned
        S = np.empty((r.size, len(free)))
        for j in range(len(free)):
            h = 1e-4 * sc[j]
            xp = x.copy()
            xp[j] += h
            S[:, j] = (res(xp) - r) / h
        A = S.T @ S
        b = -S.T @ r
        improved = False
        for _ in range(12):
            dx = np.linalg.solve(A + mu * np.diag(np.diag(A) + 1e-12), b)
            xn = x + dx
            xn[nonneg] = np.maximum(xn[nonneg], 0.0)
            rn = res(xn)
            cn = float(rn @ rn)
            if cn < cost:
                improved = True
                break
            mu *= 10.0
        if not improved:
            break
        step = np.max(np.abs(xn - x) / sc)
        x, r, cost, mu = xn, rn, cn, max(mu / 10.0, 1e-9)
        if step < 1e-7:
            break
    s2 = cost / max(r.size - len(free), 1)
    cov = np.linalg.pinv(S.T @ S) * s2
    err = {n: float(math.sqrt(max(c, 0.0))) for n, c in zip(free, np.diag(cov))}
    return dict(q, **dict(zip(free, x))), err, it


_SCALES = {
    "beta1": 0.1,
    "beta2": 0.01,
    "beta3": 0.01,
    "L": 0.01,
    "theta_offset": 0.01,
    "theta_init": 0.01,
    "thetadot_init": 0.1,
}


def fit_damping(record: Record, skip: int = 1) -> DampingFit:
    """Run the three steps on a free-decay record, starting at turning point ``skip``."""
    sw = _Swing(record, record.params.g, skip)
    stages = _initial_estimates(sw)
    # The Coulomb/viscous split has several local optima on real swings: update
    # from the step-2 and step-1 estimates and from pure Coulomb friction
    # (the mean decrement), and keep the best.
    mean_dec = float(np.mean(-np.diff(sw.amplitudes(sw.offset0))))
    step2 = stages["step2_large_angle_exponential"]
    omega0 = math.sqrt(sw.g / step2["L"])
    starts = [step2, stages["step1_small_angle_linear"], dict(step2, beta1=mean_dec * omega0**2 / 2.0, beta2=0.0)]
    best = None
    for start in starts:
        q = dict(start, theta_offset=sw.offset0, theta_init=sw.theta_init0, thetadot_init=sw.thetadot_init0)
        q, err, iterations = _update(sw, q, PHYSICS + NUISANCE, _SCALES)
        r = sw.residual(q)
        if best is None or r @ r < best[0]:
            best = (float(r @ r), q, err, iterations)
    _, q, err, iterations = best
    return DampingFit(
        physics={k: q[k] for k in PHYSICS},
        stderr={k: err[k] for k in PHYSICS},
        nuisance={k: q[k] for k in NUISANCE},
        stages=stages,
        envelope_error=sw.envelope_error(q),
        iterations=iterations,
        measured=np.stack([sw.ex.t.to_numpy(), sw.amplitudes(q["theta_offset"])], axis=1),
        simulated=sw.turning_points(q),
    )


def predict(fit: DampingFit, record: Record, skip: int = 1) -> dict[str, Any]:
    """Envelope error on another record with the physics fixed.

    Only the record's own nuisance parameters (offset, release velocity) are fitted. Returns the maximum relative envelope error and the
    turning points.
    """
    sw = _Swing(record, record.params.g, skip)
    q = dict(fit.physics, theta_offset=sw.offset0, theta_init=sw.theta_init0, thetadot_init=sw.thetadot_init0)
    q, _, _ = _update(sw, q, NUISANCE, _SCALES)
    return {
        "envelope_error": sw.envelope_error(q),
        "nuisance": {k: q[k] for k in NUISANCE},
        "measured": np.stack([sw.ex.t.to_numpy(), sw.amplitudes(q["theta_offset"])], axis=1),
        "simulated": sw.turning_points(q),
    }
