"""Two-parameter curves and the hybrid loop's bifurcations (issue 32), against the scans they replace.

* ``pd_curve``: the semi-trivial solution's period-doubling curve over Fig. 10's omega_hat range
  (``pendsweep curve``) against the Floquet grid scan of the same range (``pendsweep hopf
  --method floquet``, 25 and 241 points, one core), with their largest disagreement.
* ``hybrid_pd``: the hybrid loop's period doubling at the paper's 18 ms with first-order prediction
  (``continue --backend substructured``) against the fine noise-free substructured sweep that
  brackets it (0.01 N steps, each point kicked from rest and its growth fitted over 600 periods).
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from ..analysis.continuation.curve_run import config_from_file, run_curve
from ..analysis.continuation.run import ContinuationConfig, run_continuation, write_json
from ..model.params import TABLE_IV
from ..studies.hopf import HopfConfig, fe_for_omega_hat, hopf_floquet, run_hopf
from ..studies.sweep import SweepConfig, run_sweep, value_range
from .registry import benchmark, best_of

SMOOTH = {"fe": 2.5, "b1": 0.0, "b3": 0.0}
#: Fig. 10's omega_hat range.
OMEGA_HAT = (0.88, 1.12)
#: The loop without noise or quantisation (a deterministic map, as the continuation sees it).
NOISE_FREE = {"force_noise": 0.0, "lvdt_noise": 0.0, "encoder_resolution": 0.0, "lvdt_resolution": 0.0}


@benchmark("curves")
def bench_curves(quick: bool) -> dict:
    """PD curve against the Floquet grid scan; the hybrid loop's PD against the sweep that brackets it."""
    with tempfile.TemporaryDirectory() as tmp:
        return _pd_curve(Path(tmp), quick) | _hybrid_pd(quick)


def _pd_curve(tmp: Path, quick: bool) -> dict:
    base = TABLE_IV.replace(**SMOOTH)
    fe_range = tuple(fe_for_omega_hat(base, w) for w in OMEGA_HAT)
    start = tmp / "c.json"
    write_json(run_continuation(ContinuationConfig("alpha", 10.0, 25.0, SMOOTH, max_period=1)), start)
    config = config_from_file(start, 0, second="fe", start=fe_range[0], stop=fe_range[1], first_limits=(0.0, 60.0))

    def curve():
        out = tmp / "curve.parquet"
        out.unlink(missing_ok=True)
        return run_curve(config, out)

    rows = curve()
    t_curve = best_of(curve, 1 if quick else 2)
    grids = {}
    for n in (25,) if quick else (25, 241):
        hopf = HopfConfig(omega_hat=tuple(np.linspace(*OMEGA_HAT, n)), methods=("floquet",), model=SMOOTH)
        table = run_hopf(hopf, n_jobs=1)
        grids[n] = (best_of(lambda hopf=hopf: run_hopf(hopf, n_jobs=1), 1), table)
    # The curve's points against the Floquet boundary at their own fe (400 steps per period, as the curve).
    sample = rows.sort_values("point").iloc[:: max(1, len(rows) // 6)]
    worst = max(
        abs(alpha / hopf_floquet(base.replace(fe=fe), steps=400)["alpha_H"] - 1.0)
        for alpha, fe in zip(sample["alpha"], sample["fe"])
    )
    out = {
        "pd_curve_points": int(len(rows)),
        "pd_curve_seconds_one_core": t_curve,
        "pd_curve_fe_range_Hz": list(fe_range),
        "pd_curve_events": sorted(set(rows["event"]) - {""}),
    }
    for n, (seconds, _) in grids.items():
        out[f"floquet_grid_{n}_seconds_one_core"] = seconds
        out[f"pd_curve_over_floquet_grid_{n}_time"] = t_curve / seconds
    out["pd_curve_vs_floquet_relative_max"] = worst
    return out


def _hybrid_pd(quick: bool) -> dict:
    """Continuation's hybrid PD and the bracket a noise-free sweep in 0.01 N steps finds.

    The sweep is the paper's protocol point by point (``--mode fresh``): the oscillator from rest, the
    pendulum kicked to 1e-4 rad, 100 transient periods, then the log of the per-period max|theta| fitted
    over 600 recorded periods. A negative slope is below the period doubling (the kick decays), a positive
    one above it (it grows); the bracket is the last negative and the first positive value. A settled
    swing cannot tell the side that close to the bifurcation: both its growth and its decay slow down there.
    """
    config = ContinuationConfig("alpha", 15.3, 15.9, SMOOTH, max_period=1, backend="substructured")
    doc = run_continuation(config)
    t_cont = best_of(lambda: run_continuation(config), 1)
    pd = next(b["value"] for b in doc["bifurcations"] if b["type"] == "period-doubling")
    step = 0.02 if quick else 0.01
    half = 0.06 if quick else 0.1
    lo, hi = math.floor((pd - half) / step) * step, math.ceil((pd + half) / step) * step
    sweep = SweepConfig(
        "alpha",
        tuple(value_range(lo, hi, step)),
        model=SMOOTH,
        backend="substructured",
        backend_options=NOISE_FREE,
        mode="fresh",
        initial=(0.0, 0.0, 1e-4, 0.0),
        transient_periods=100,
        record_periods=600,
    )
    t0 = time.perf_counter()
    rows = run_sweep(sweep, n_jobs=1)
    t_sweep = time.perf_counter() - t0
    slopes = {
        float(alpha): float(np.polyfit(group["period"], np.log(group["theta_absmax"]), 1)[0])
        for alpha, group in rows.groupby("alpha")
    }
    values = sorted(slopes)
    below = max((a for a in values if slopes[a] < 0), default=math.nan)
    above = min((a for a in values if slopes[a] > 0), default=math.nan)
    return {
        "hybrid_pd_continuation_N": pd,
        "hybrid_pd_shift_from_emulated": pd / 16.0971804 - 1.0,
        "hybrid_pd_continuation_seconds_one_core": t_cont,
        "hybrid_pd_sweep_bracket_N": [below, above],
        "hybrid_pd_sweep_bracket_consistent": bool(all((slopes[a] > 0) == (a > below) for a in values)),
        "hybrid_pd_inside_sweep_bracket": bool(below <= pd <= above),
        "hybrid_pd_sweep_step_N": step,
        "hybrid_pd_sweep_points": len(sweep.values),
        "hybrid_pd_sweep_seconds_one_core": t_sweep,
        "hybrid_pd_continuation_over_sweep_time": t_cont / t_sweep,
    }
