"""AUTO-07p runs for the period-doubling curve of the pendulum-oscillator.

Run by ``run_pd_curve.py`` under the Python that AUTO-07p's own ``auto``
module works with (Debian's /usr/lib/auto-07p/python reads solution files
with ``fdata == []`` on a numpy array, which numpy >= 2 rejects; without numpy
it falls back to plain Python, so the default is /usr/bin/python3 with no
numpy). It imports nothing from pendsweep.

    /usr/bin/python3 scripts/auto/auto_pd.py CONFIG.json OUT.json

CONFIG.json: ``workdir`` (an existing directory holding pendulum.f90 and
c.pendulum), ``ntst``, ``par`` (name -> value, AUTO parameter names of
c.pendulum), ``alpha_stop`` [N], ``fe_range`` [Hz, Hz], ``fe_targets`` [Hz],
``ds``, ``dsmax``, ``nmx``. OUT.json: the PD point of run 1, the user points
(UZ, at ``fe_targets``) of the PD curve, and wall times.

Runs, all in ``workdir``:

1. the semi-trivial orbit at fe = 2.5 Hz continued in alpha from 10 N
   (IPS=2, ICP=[alpha, period]), period doubling located (ISP=2);
2. from that PD point, the PD curve in (alpha, fe) (ISW=2,
   ICP=[alpha, fe, period]): AUTO's start-up run, then on to one end of
   ``fe_range``, then back over the whole range, where the UZ points lie
   (and once more for any UZ point AUTO skipped).
"""

import json
import os
import subprocess
import sys
import time

AUTO_DIR = os.environ.get("AUTO_DIR", "/usr/lib/auto-07p")
sys.path.insert(0, os.path.join(AUTO_DIR, "python"))

import auto  # noqa: E402  (AUTO-07p's Python interface)


def solutions(bd, kind):
    """(fe, alpha, period, label) of every solution of type ``kind`` in ``bd``."""
    return [(s["fe"], s["alpha"], s["period"], s["LAB"]) for s in bd(kind)]


def main(config_path, out_path):
    with open(config_path) as f:
        cfg = json.load(f)
    out_path = os.path.abspath(out_path)
    os.chdir(cfg["workdir"])
    env = dict(os.environ, AUTO_DIR=AUTO_DIR)

    t0 = time.perf_counter()
    subprocess.run(
        ["make", "-s", "-f", os.path.join(AUTO_DIR, "cmds", "cmds.make"), "EQUATION_NAME=pendulum", "pendulum.exe"],
        check=True,
        env=env,
        stdout=subprocess.DEVNULL,
    )
    t_compile = time.perf_counter() - t0

    ntst = int(cfg["ntst"])
    common = dict(NTST=ntst, PAR=cfg["par"])

    # Run 1: alpha continuation of the semi-trivial orbit, PD detection.
    t0 = time.perf_counter()
    r1 = auto.run(e="pendulum", c="pendulum", UZSTOP={"alpha": cfg["alpha_stop"]}, **common)
    t_run1 = time.perf_counter() - t0
    pds = solutions(r1, "PD")
    if not pds:
        raise SystemExit("run 1 found no period doubling")

    # Run 2: the PD curve in (alpha, fe).
    lo, hi = cfg["fe_range"]
    ds, dsmax = cfg["ds"], cfg["dsmax"]
    curve = dict(
        ISW=2,
        ICP=["alpha", "fe", "period"],
        ISP=0,
        ILP=0,
        DS=ds,
        DSMAX=dsmax,
        NMX=cfg["nmx"],
        UZSTOP={"fe": [lo, hi]},
        NTST=ntst,
    )
    t0 = time.perf_counter()
    start = auto.run(r1("PD1"), **curve)  # AUTO's start-up run (the PD eigenfunction)
    to_end = auto.run(start, **curve)
    end = to_end("UZ")[-1]
    if not (abs(end["fe"] - lo) < 1e-6 or abs(end["fe"] - hi) < 1e-6):
        raise SystemExit(f"run 2 stopped at fe = {end['fe']} before the end of the range")
    back = auto.run(end, **dict(curve, DS=-ds, UZR={"fe": cfg["fe_targets"]}))
    t_curve = time.perf_counter() - t0
    last = back()[-1]
    if not (abs(last["fe"] - lo) < 1e-6 or abs(last["fe"] - hi) < 1e-6) or abs(last["fe"] - end["fe"]) < 1e-6:
        raise SystemExit(f"the run back stopped at fe = {last['fe']} before the other end of the range")

    points = [p for p in solutions(back, "UZ") if not (abs(p[0] - lo) < 1e-9 or abs(p[0] - hi) < 1e-9)]

    # AUTO skips a user point crossed on the step right after it located another one (targets
    # close together near the tongue's tip): go over the range again for those only.
    t0 = time.perf_counter()
    passes = 1
    while True:
        missed = [f for f in cfg["fe_targets"] if not any(abs(p[0] - f) < 1e-7 for p in points)]
        if not missed:
            break
        if passes == 4:
            raise SystemExit(f"AUTO found no user point at fe = {missed}")
        again = auto.run(end, **dict(curve, DS=-ds, UZR={"fe": missed}))
        points += [p for p in solutions(again, "UZ") if any(abs(p[0] - f) < 1e-7 for f in missed)]
        passes += 1
    t_extra = time.perf_counter() - t0
    points.sort()
    alpha_path = [a for br in back for a in br["alpha"]]
    fe_path = [x for br in back for x in br["fe"]]
    n_steps = len(alpha_path)
    out = dict(
        ntst=ntst,
        pd=dict(fe=pds[0][0], alpha=pds[0][1], period=pds[0][2]),
        uz=[dict(fe=p[0], alpha=p[1], period=p[2]) for p in points],
        ends=[dict(fe=s["fe"], alpha=s["alpha"]) for s in (end, last)],
        curve_points=n_steps,
        path=dict(alpha=alpha_path, fe=fe_path),
        wall_s=dict(compile=t_compile, run1=t_run1, curve=t_curve, extra_passes=t_extra),
        passes=passes,
    )
    with open(out_path, "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
