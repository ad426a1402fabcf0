"""AUTO-07p as an independent peer for pendsweep's period-doubling curve.

    .venv/bin/python scripts/auto/run_pd_curve.py

The emulated pendulum-oscillator, Eq. (11), with the Table IV parameters and
b1 = b3 = 0: the period doubling of the semi-trivial orbit (pendulum at rest)
at fe = 2.5 Hz and its curve in (alpha, fe) over fe = 1.984..2.526 Hz
(omega_hat 0.88..1.12), computed

* by AUTO-07p (scripts/auto/pendulum.f90, c.pendulum, auto_pd.py: orthogonal
  collocation, NTST mesh intervals of NCOL = 4 points, for each --ntst);
* by ``pendsweep continue`` + ``pendsweep curve`` (shooting, RK4, dt = 1 ms);
* by pendsweep's Floquet boundary ``hopf_floquet(..., steps=2000)`` (the
  damped Mathieu equation of theta = 0; the same boundary, since Eq. (11)
  linearised at theta = 0 is that equation), and the same root refined
  (brentq to 1e-13 N) with 2000 and 4000 RK4 steps per period.

The comparison points are the ``pendsweep curve`` points themselves (no
interpolation): AUTO puts user points (UZ) at their fe values. Prints and
writes (to --out) the table, relative differences and wall times, each with
the 1-minute load average before and after.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from pendsweep.analysis.semi_trivial import floquet_multipliers, hopf_floquet
from pendsweep.model.params import TABLE_IV

HERE = Path(__file__).resolve().parent
BIN = Path(sys.executable).parent
FE_RANGE = (1.984, 2.526)
OMEGA_HAT_RANGE = (0.88, 1.12)
#: AUTO parameter names (c.pendulum parnames) -> pendsweep ModelParams fields.
AUTO_PARS = ("m", "l", "b2", "g", "M", "C", "K")


def load() -> float:
    """1-minute load average."""
    return float(Path("/proc/loadavg").read_text().split()[0])


def timed(cmd: list[str], **kw) -> dict:
    """Run ``cmd``; its wall time [s] and the load before and after."""
    before = load()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, **kw)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, cmd))} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return dict(wall_s=wall, load_before=before, load_after=load(), stdout=proc.stdout)


def model():
    """Table IV with smooth damping, checked against the numbers pendulum.f90's STPNT starts from."""
    params = TABLE_IV.replace(b1=0.0, b3=0.0)
    if params.k3 != 0.0:
        raise SystemExit("pendulum.f90 has no cubic spring (k3 = 0)")
    source = (HERE / "pendulum.f90").read_text()
    stpnt = source[source.index("SUBROUTINE STPNT") :]
    hard = {
        int(k): float(v.replace("D", "E")) for k, v in re.findall(r"PAR\((\d+)\)\s*=\s*([-0-9.D+]+)\s*$", stpnt, re.M)
    }
    expected = {1: 10.0, 2: 2.5, **{i + 3: getattr(params, name) for i, name in enumerate(AUTO_PARS)}}
    for k, v in expected.items():
        if not math.isclose(hard.get(k, math.nan), v, rel_tol=1e-15):
            raise SystemExit(f"pendulum.f90 STPNT has PAR({k}) = {hard.get(k)}, pendsweep's value is {v}")
    return params


def pendsweep_curve(workdir: Path, repeats: int) -> tuple[pd.DataFrame, dict]:
    """``pendsweep continue`` and ``curve`` (the brief's commands), timed ``repeats`` times each."""
    cont_json = workdir / "auto_c.json"
    curve_pq = workdir / "auto_curve.parquet"
    cont = [str(BIN / "pendsweep"), "continue", "alpha", "--from", "10", "--to", "25", "--set", "b1=0", "--set", "b3=0"]
    cont += ["--max-period", "1", "-o", str(cont_json), "--no-progress"]
    curve = [str(BIN / "pendsweep"), "curve", str(cont_json), "--second", "fe", "--from", str(FE_RANGE[0])]
    curve += ["--to", str(FE_RANGE[1]), "-o", str(curve_pq), "--no-progress"]
    times = dict(continue_=[], curve=[])
    for _ in range(repeats):
        times["continue_"].append(timed(cont))
        if curve_pq.exists():
            curve_pq.unlink()  # no --resume: a fresh curve each time
        times["curve"].append(timed(curve))
    pd_line = re.search(r"period-doubling at alpha = ([0-9.eE+-]+)", times["continue_"][-1]["stdout"])
    times["pd_alpha_printed"] = float(pd_line.group(1)) if pd_line else math.nan
    frame = pd.read_parquet(curve_pq).sort_values("fe").reset_index(drop=True)
    return frame, times


def pick(frame: pd.DataFrame, n: int) -> pd.DataFrame:
    """About ``n`` curve points evenly spread by index, with fe = 2.5 Hz and the tongue's tip."""
    idx = set(np.linspace(0, len(frame) - 1, n).round().astype(int))
    idx.add(int(frame["alpha"].idxmin()))
    idx.add(int((frame["fe"] - 2.5).abs().idxmin()))
    return frame.loc[sorted(idx), ["fe", "alpha", "event"]].reset_index(drop=True)


def run_auto(ntst: int, params, targets: list[float], args, workdir: Path) -> dict:
    """auto_pd.py under AUTO's Python, in a fresh directory; its JSON plus the subprocess wall time."""
    run_dir = workdir / f"ntst{ntst}"
    shutil.rmtree(run_dir, ignore_errors=True)
    run_dir.mkdir(parents=True)
    for name in ("pendulum.f90", "c.pendulum"):
        shutil.copy(HERE / name, run_dir / name)
    lo, hi = FE_RANGE
    config = dict(
        workdir=str(run_dir),
        ntst=ntst,
        par={"alpha": 10.0, "fe": 2.5, **{name: getattr(params, name) for name in AUTO_PARS}},
        alpha_stop=25.0,
        fe_range=[lo, hi],
        fe_targets=[f for f in targets if lo < f < hi],
        ds=0.05,
        dsmax=args.dsmax,
        nmx=20000,
    )
    (run_dir / "config.json").write_text(json.dumps(config))
    # One OpenMP thread: AUTO's default (all cores) was 2-15x slower on a loaded 2-core machine.
    env = dict(os.environ, OMP_NUM_THREADS="1")
    cmd = [args.auto_python, str(HERE / "auto_pd.py"), str(run_dir / "config.json"), str(run_dir / "out.json")]
    t = timed(cmd, env=env)
    (run_dir / "auto.log").write_text(t.pop("stdout"))
    out = json.loads((run_dir / "out.json").read_text())
    alpha, fe = np.array(out["path"]["alpha"]), np.array(out["path"]["fe"])
    if alpha.min() <= 0 or not (np.all(np.diff(fe) < 0) or np.all(np.diff(fe) > 0)):
        raise SystemExit(f"NTST={ntst}: the AUTO curve left alpha > 0 or turned in fe (lower --dsmax)")
    out["subprocess"] = t
    del out["path"]
    return out


def auto_alpha(out: dict, fe: float) -> tuple[float, float]:
    """AUTO's alpha [N] at ``fe`` (a UZ or end point) and the fe it was found at."""
    cand = out["uz"] + out["ends"]
    best = min(cand, key=lambda p: abs(p["fe"] - fe))
    if abs(best["fe"] - fe) > 1e-8:
        raise SystemExit(f"AUTO has no point at fe = {fe} (nearest {best['fe']})")
    return best["alpha"], best["fe"]


def floquet_fine(params, fe: float, alpha0: float, steps: int) -> float:
    """The Floquet boundary near ``alpha0`` to 1e-13 N (log of the largest |multiplier| = 0)."""
    p = params.replace(fe=fe)

    def g(a):
        return float(np.log(np.abs(floquet_multipliers(p.replace(alpha=a), steps)).max()))

    lo, hi = alpha0 * (1 - 1e-4), alpha0 * (1 + 1e-4)
    if g(lo) > 0 or g(hi) < 0:
        raise SystemExit(f"Floquet bracket failed at fe = {fe}")
    return brentq(g, lo, hi, xtol=1e-13, rtol=4 * np.finfo(float).eps, maxiter=200)


def hopf_timing(grid: int, workdir: Path) -> dict:
    out = workdir / f"hopf{grid}.parquet"
    cmd = [str(BIN / "pendsweep"), "hopf", "--what", f"{OMEGA_HAT_RANGE[0]}:{OMEGA_HAT_RANGE[1]}:{grid}"]
    cmd += ["--method", "floquet", "--set", "b1=0", "--set", "b3=0", "-o", str(out), "--overwrite", "--no-progress"]
    t = timed(cmd)
    t.pop("stdout")
    t["points"] = grid
    return t


def rel(a: float, b: float) -> float:
    return abs(a - b) / abs(b)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ntst", default="20,50,100", help="AUTO mesh intervals, comma separated (default 20,50,100)")
    ap.add_argument("--points", type=int, default=12, help="comparison points from the pendsweep curve (default 12)")
    ap.add_argument("--dsmax", type=float, default=0.05, help="AUTO's largest step on the PD curve (default 0.05)")
    ap.add_argument("--repeats", type=int, default=2, help="timed runs of each pendsweep command (default 2)")
    ap.add_argument("--auto-python", default="/usr/bin/python3", help="Python that runs AUTO's auto module")
    ap.add_argument("--out", default="results/auto", help="output directory (default results/auto)")
    args = ap.parse_args()
    ntsts = [int(x) for x in args.ntst.split(",")]

    params = model()
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    workdir = Path(tempfile.mkdtemp(prefix="pendsweep-auto-"))

    frame, ps_times = pendsweep_curve(workdir, args.repeats)
    table = pick(frame, args.points)
    targets = [float(f) for f in table["fe"]]

    autos = {n: run_auto(n, params, targets, args, workdir) for n in ntsts}

    rows = []
    for fe, a_curve in zip(table["fe"], table["alpha"]):
        row = dict(fe=fe, omega_hat=params.replace(fe=fe).omega_hat, alpha_curve=a_curve)
        row["alpha_floquet"] = hopf_floquet(params.replace(fe=fe), steps=2000)["alpha_H"]
        row["alpha_floquet_fine"] = floquet_fine(params, fe, row["alpha_floquet"], 2000)
        row["alpha_floquet_fine4000"] = floquet_fine(params, fe, row["alpha_floquet"], 4000)
        for n, out in autos.items():
            a, fe_auto = auto_alpha(out, fe)
            row[f"alpha_auto{n}"] = a
            row[f"fe_miss{n}"] = fe_auto - fe
        rows.append(row)
    res = pd.DataFrame(rows)

    n_ref = max(ntsts)
    ref = res[f"alpha_auto{n_ref}"]
    summary = dict(
        pd_alpha_at_2_5=dict(
            pendsweep_continue=ps_times["pd_alpha_printed"],
            auto_run1={n: o["pd"]["alpha"] for n, o in autos.items()},
            floquet=hopf_floquet(params.replace(fe=2.5), steps=2000)["alpha_H"],
            floquet_fine=floquet_fine(params, 2.5, 16.0971804, 2000),
        ),
        floquet_steps_effect=float((abs(res["alpha_floquet_fine"] - res["alpha_floquet_fine4000"]) / ref).max()),
        hopf_floquet_vs_fine=float((abs(res["alpha_floquet"] - res["alpha_floquet_fine"]) / ref).max()),
    )
    diffs = {}
    for n in ntsts:
        a = res[f"alpha_auto{n}"]
        d_curve = abs(res["alpha_curve"] - a) / a
        d_floq = abs(res["alpha_floquet"] - a) / a
        d_fine = abs(res["alpha_floquet_fine4000"] - a) / a
        res[f"rel_curve{n}"] = d_curve
        res[f"rel_floquet{n}"] = d_floq
        res[f"rel_fine{n}"] = d_fine
        diffs[n] = {
            "vs_curve_max": float(d_curve.max()),
            "vs_curve_median": float(d_curve.median()),
            "vs_floquet_max": float(d_floq.max()),
            "vs_floquet_median": float(d_floq.median()),
            "vs_floquet_fine_max": float(d_fine.max()),
            "vs_floquet_fine_median": float(d_fine.median()),
            "max_fe_miss": float(res[f"fe_miss{n}"].abs().max()),
            "curve_points": autos[n]["curve_points"],
        }
    summary["rel_diffs"] = diffs

    timings = dict(
        pendsweep_continue=[{k: v for k, v in t.items() if k != "stdout"} for t in ps_times["continue_"]],
        pendsweep_curve=[{k: v for k, v in t.items() if k != "stdout"} for t in ps_times["curve"]],
        pendsweep_curve_points=len(frame),
        auto={n: dict(inner=o["wall_s"], subprocess=o["subprocess"]) for n, o in autos.items()},
        hopf_floquet=[hopf_timing(g, workdir) for g in (25, 241)],
        cpus=os.cpu_count(),
    )
    summary["timings"] = timings

    res.to_csv(out_dir / "pd_curve_compare.csv", index=False)
    (out_dir / "pd_curve_summary.json").write_text(json.dumps(summary, indent=1, default=float))

    pd.set_option("display.width", 250)
    pd.set_option("display.max_columns", 40)
    cols = ["fe", "omega_hat", f"alpha_auto{n_ref}", "alpha_curve", "alpha_floquet", "alpha_floquet_fine4000"]
    cols += [f"rel_curve{n_ref}", f"rel_floquet{n_ref}"] + [f"rel_fine{n}" for n in ntsts]
    print(res[cols].to_string(float_format=lambda v: f"{v:.10g}"))
    print(json.dumps(summary, indent=1, default=float))
    print(f"wrote {out_dir / 'pd_curve_compare.csv'} and {out_dir / 'pd_curve_summary.json'} (AUTO runs in {workdir})")


if __name__ == "__main__":
    main()
