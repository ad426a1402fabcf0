"""Signature diagnostics: features of the residuals and the swing that point to a cause.

* residual spectra (Welch);
* cross-correlation of residuals with the input at lags (a peak away from
  lag 0 points to a delay), and of the actuator displacement x with its
  command in substructured records (the lag of the peak is the delay);
* decay envelope and decrement per half cycle against amplitude: a constant
  decrement is Coulomb friction, one proportional to amplitude is viscous,
  one growing as amplitude squared is air drag;
* swing frequency against amplitude (the backbone), compared with the ideal
  pendulum ``omega0 (1 - A^2/16)``;
* mean offsets: of the residuals, and of the swing's turning points.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd
from scipy.signal import welch

from .signals import smoothed


def extrema(t: np.ndarray, theta: np.ndarray, min_amplitude: float = 0.0) -> pd.DataFrame:
    """Turning points of a swing: times and angles of successive maxima and minima.

    The angle is smoothed (cubic Savitzky-Golay, which also bridges encoder
    steps); a turning point is a sign change of the smoothed velocity, refined
    by a parabola through the three samples around it.

    Returns
    -------
    DataFrame
        Columns ``t`` [s], ``theta`` [rad] (signed), ``kind`` (+1 maximum, -1 minimum).
    """
    dt = float(t[1] - t[0])
    th, thd = smoothed(theta, dt)
    s = np.sign(thd)
    idx = np.flatnonzero((s[:-1] > 0) & (s[1:] <= 0) | (s[:-1] < 0) & (s[1:] >= 0))
    rows = []
    for i in idx:
        kind = 1 if s[i] > 0 else -1
        j = i if abs(thd[i]) < abs(thd[i + 1]) else i + 1
        j = min(max(j, 1), len(th) - 2)
        a, b, c = th[j - 1], th[j], th[j + 1]
        den = a - 2.0 * b + c
        # Refine only when the local parabola bends the right way (quantisation can flip it).
        shift = float(np.clip(0.5 * (a - c) / den, -1.0, 1.0)) if den * kind < 0 else 0.0
        rows.append((t[0] + (j + shift) * dt, b - 0.25 * (a - c) * shift, kind))
    df = pd.DataFrame(rows, columns=["t", "theta", "kind"])
    # Keep alternating turning points only (noise near rest makes spurious pairs).
    keep = [0] if len(df) else []
    for k in range(1, len(df)):
        if df.kind.iloc[k] != df.kind.iloc[keep[-1]]:
            keep.append(k)
        elif abs(df.theta.iloc[k]) > abs(df.theta.iloc[keep[-1]]):
            keep[-1] = k
    df = df.iloc[keep].reset_index(drop=True)
    return df[np.abs(df.theta) >= min_amplitude].reset_index(drop=True)


def envelope(t: np.ndarray, theta: np.ndarray, offset: float = 0.0, min_amplitude: float = 0.0) -> pd.DataFrame:
    """Half-cycle amplitudes about ``offset``: columns ``t``, ``amplitude`` [rad]."""
    ex = extrema(t, theta - offset, min_amplitude)
    return pd.DataFrame({"t": ex.t, "amplitude": np.abs(ex.theta)})


def decrement_fit(env: pd.DataFrame) -> dict[str, float]:
    """Decrement per half cycle against mean amplitude, ``dA = c0 + c1 A + c2 A^2``.

    For ``theta'' + beta1 sgn + beta2 theta' + beta3 theta'|theta'| + omega^2 theta = 0``
    averaging gives ``dA = 2 beta1/omega^2 + (pi beta2 / (2 omega)) A + (4/3) beta3 A^2``.
    Returns c0, c1, c2 and the share of each term in the decrement at the mean amplitude.
    """
    a = env.amplitude.to_numpy()
    if len(a) < 5:
        return {}
    amp = 0.5 * (a[:-1] + a[1:])
    dec = a[:-1] - a[1:]
    design = np.stack([np.ones_like(amp), amp, amp * amp], axis=1)
    coef, *_ = np.linalg.lstsq(design, dec, rcond=None)
    mean_a = float(amp.mean())
    terms = coef * np.array([1.0, mean_a, mean_a**2])
    total = float(np.sum(np.abs(terms))) or 1.0
    return {
        "c0": float(coef[0]),
        "c1": float(coef[1]),
        "c2": float(coef[2]),
        "mean_amplitude": mean_a,
        "share_constant": float(abs(terms[0]) / total),
        "share_proportional": float(abs(terms[1]) / total),
        "share_quadratic": float(abs(terms[2]) / total),
    }


def backbone(ex: pd.DataFrame) -> pd.DataFrame:
    """Swing frequency [Hz] against amplitude [rad] from successive half periods."""
    if len(ex) < 3:
        return pd.DataFrame(columns=["amplitude", "frequency"])
    half = np.diff(ex.t.to_numpy())
    amp = 0.5 * (np.abs(ex.theta.to_numpy()[:-1]) + np.abs(ex.theta.to_numpy()[1:]))
    return pd.DataFrame({"amplitude": amp, "frequency": 0.5 / half})


def cross_correlation(residual: np.ndarray, signal: np.ndarray, dt: float, max_lag: float) -> pd.DataFrame:
    """Normalised cross-correlation ``corr(residual(t), signal(t - lag))`` for lags in ``[-max_lag, max_lag]``."""
    r = residual - residual.mean()
    s = signal - signal.mean()
    norm = math.sqrt(float(r @ r) * float(s @ s)) or 1.0
    k = int(max_lag / dt)
    lags = np.arange(-k, k + 1)
    n = len(r)
    c = [float(r[max(L, 0) : n + min(L, 0)] @ s[max(-L, 0) : n - max(L, 0)]) / norm for L in lags]
    return pd.DataFrame({"lag": lags * dt, "corr": c})


def residual_spectrum(residual: np.ndarray, dt: float) -> pd.DataFrame:
    """Welch power spectral density of a residual: ``frequency`` [Hz], ``psd`` [unit^2/Hz]."""
    f, p = welch(residual, fs=1.0 / dt, nperseg=min(len(residual), 4096))
    return pd.DataFrame({"frequency": f, "psd": p})


def summarize(replay, nominal_sim: dict[str, np.ndarray]) -> dict[str, Any]:
    """Numbers of every signature for the report (residuals are of the nominal model)."""
    out: dict[str, Any] = {}
    for c in replay.channels:
        res = nominal_sim[c] - replay.meas[c]
        spec = residual_spectrum(res[np.isfinite(res)], replay.dt)
        out[f"{c}_residual_mean"] = float(np.nanmean(res))
        out[f"{c}_residual_peak_hz"] = float(spec.frequency[spec.psd[1:].idxmax()]) if len(spec) > 1 else math.nan
        if getattr(replay, "force", None) is not None and np.all(np.isfinite(res)):
            xc = cross_correlation(res, replay.force, replay.dt, 0.1)
            best = xc.iloc[int(np.argmax(np.abs(xc["corr"].to_numpy())))]
            out[f"{c}_xcorr_Fe_peak_lag_s"] = float(best.lag)
            out[f"{c}_xcorr_Fe_peak"] = float(best["corr"])
    if replay.kind == "substructured":
        # The actuator's delay seen directly: x against the command.
        xc = cross_correlation(replay.meas["y"], replay.meas["y_cmd"], replay.dt, 0.05)
        out["x_lags_y_cmd_by_s"] = float(xc.lag[int(np.argmax(xc["corr"].to_numpy()))])
    if replay.kind != "free_decay" or "theta" not in replay.meas:
        return out  # decay and backbone describe a free swing; a forced swing's amplitude is set by the forcing
    # Turning points only where the data move: near rest, noise and quantisation make spurious ones.
    moving = replay.moving
    ex = extrema(replay.t[moving], replay.meas["theta"][moving], min_amplitude=3 * replay.noise["theta"] + 0.005)
    if len(ex) >= 3:
        mids = 0.5 * (ex.theta.to_numpy()[:-1] + ex.theta.to_numpy()[1:])
        out["theta_turning_point_midline"] = float(np.median(mids))
        env = pd.DataFrame({"t": ex.t, "amplitude": np.abs(ex.theta - np.median(mids))})
        out.update({f"decrement_{k}": v for k, v in decrement_fit(env).items()})
        bb = backbone(ex)
        out["frequency_at_small_amplitude_hz"] = float(bb.frequency[bb.amplitude.idxmin()])
        out["frequency_at_large_amplitude_hz"] = float(bb.frequency[bb.amplitude.idxmax()])
        out["nominal_small_amplitude_frequency_hz"] = math.sqrt(replay.nominal["g"] / replay.nominal["l"]) / (
            2 * math.pi
        )
    return out


def _reference_frequency(replay) -> tuple[float, str]:
    """The frequency residual peaks are reported against: f_e, or the measured swing frequency of a free decay."""
    if replay.kind != "free_decay":
        fe = replay.record.forcing.get("fe", replay.nominal["fe"])
        return float(fe), "f_e"
    theta = replay.meas["theta"][replay.eval_idx]
    crossings = np.flatnonzero(np.diff(np.signbit(theta - np.mean(theta))))
    if len(crossings) >= 3:
        return float((len(crossings) - 1) / (2.0 * (crossings[-1] - crossings[0]) * replay.dt)), "f_swing"
    return math.sqrt(replay.nominal["g"] / replay.nominal["l"]) / (2.0 * math.pi), "f_swing"


def residual_signature(problem, fit, peaks: int = 3) -> dict[str, Any]:
    """What the verdict model leaves, per record and channel (out-of-fold residuals).

    ``peaks``: the strongest spectral peaks as multiples of the reference frequency
    (f_e for forced records, the swing frequency for free decays) with their share of
    the residual power; ``lag1``: lag-1 autocorrelation (about 0 for white sensor noise,
    near 1 for a structured residual); correlations (largest |corr| over lags within
    0.1 s) with the inputs: F_e, and y_cmd for substructured records; the platform's
    acceleration for the physical part; with the measured angle and angular velocity
    for free decays (a frequency or a damping error).
    """
    out: dict[str, Any] = {}
    for i, rp in enumerate(problem.replays):
        f_ref, ref_name = _reference_frequency(rp)
        rec: dict[str, Any] = {"reference": ref_name, "reference_hz": f_ref}
        idx = rp.eval_idx
        inputs = {}
        if rp.kind == "free_decay":
            th, thd = smoothed(rp.meas["theta"], rp.dt)
            inputs = {"theta": th[idx], "thetadot": thd[idx]}
        elif rp.kind == "physical":
            inputs = {"xddot": rp.motion[:: rp.per_sample, 2][idx]}
        else:
            inputs = {"Fe": rp.force[idx]}
            if rp.kind == "substructured":
                inputs["y_cmd"] = rp.command[idx]
        for c in rp.channels:
            r = fit.oof[i][c][idx]
            if not np.all(np.isfinite(r)) or np.std(r) == 0:
                continue
            spec = residual_spectrum(r, rp.dt)
            psd = spec.psd.to_numpy()
            freq = spec.frequency.to_numpy()
            local = np.flatnonzero((psd[1:-1] > psd[:-2]) & (psd[1:-1] >= psd[2:])) + 1
            top = local[np.argsort(psd[local])[::-1][:peaks]]
            entry: dict[str, Any] = {
                "rms": float(np.sqrt(np.mean(r * r))),
                "lag1": float(np.corrcoef(r[:-1], r[1:])[0, 1]),
                "peaks": [
                    {"multiple": float(freq[j] / f_ref), "hz": float(freq[j]), "power_share": float(psd[j] / psd.sum())}
                    for j in top
                ],
            }
            for name, s in inputs.items():
                xc = cross_correlation(r, s, rp.dt, 0.1)
                j = int(np.argmax(np.abs(xc["corr"].to_numpy())))
                entry[f"corr_{name}"] = float(xc["corr"].iloc[j])
                entry[f"corr_{name}_lag_s"] = float(xc.lag.iloc[j])
            rec[c] = entry
        out[rp.record.name if problem.joint else "record"] = rec
    return out
