"""Fig. 11(a) through a site, up and back down in one continuous test, against the in-process substructured sweep.

The physics check of the continuous rig test (docs/hybrid-testing.md): a
`pendsweep site` serving the Table IV rig (servo actuator, noisy sensors),
pendsweep's client sweeping alpha 0 -> 45 -> 0 N (0.5 N steps, 100 + 20
periods at 2.5 Hz) through one connection, and an operator who nudges the
pendulum by 0.1 rad (SIGUSR1 to the site) whenever the client asks, as the
in-process sweep kicks it. Then the in-process substructured continue sweep
of the same loop (``--direction loop``, kick 0.1 rad) and the emulated one.

Writes, under --out (default results/rig-check): rig.parquet (+ its time
series), local.parquet, fig11a_rig.png (the three diagrams) and
comparison.csv (per point: labels and theta_max of each), and prints the
agreement. Takes about 2 x 73 minutes of test time at the site's pace (20 to
40 minutes of wall time on a 2-core machine).

    python scripts/rig-fig11a-check.py [--out DIR] [--step 0.5] [--quick]
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/rig-check"))
    parser.add_argument("--step", type=float, default=0.5, help="alpha step [N]")
    parser.add_argument("--quick", action="store_true", help="20 + 10 periods per point, 1 N steps")
    args = parser.parse_args()
    step, transient, record = (1.0, 20, 10) if args.quick else (args.step, 100, 20)
    args.out.mkdir(parents=True, exist_ok=True)
    python = sys.executable
    site = subprocess.Popen(
        [python, "-m", "pendsweep.cli", "site", "--port", "0", "--once", "--set", "fe=2.5", "-B", "actuator=servo",
         "-o", str(args.out / "site-log.parquet")],
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    port = None
    for line in site.stderr:
        if found := re.search(r"listening on [\d.]+:(\d+)", line):
            port = int(found.group(1))
            break
    sweep = ["--from", "0", "--to", "45", "--step", str(step), "--fe", "2.5", "--transient-periods", str(transient),
             "--record-periods", str(record), "--backend", "substructured"]  # fmt: skip
    client = subprocess.Popen(
        [python, "-m", "pendsweep.cli", "alpha", *sweep, "--direction", "both", "-B", f"rig=tcp://127.0.0.1:{port}",
         "-o", str(args.out / "rig.parquet"), "--overwrite"],
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    nudges = 0
    for line in client.stderr:
        print(line, end="", flush=True)
        if "nudge it" in line:  # the operator's hand
            os.kill(site.pid, signal.SIGUSR1)
            nudges += 1
    if client.wait() != 0:
        sys.exit("the rig test failed")
    site.wait(timeout=60)
    subprocess.run([python, "-m", "pendsweep.cli", "alpha", *sweep, "--direction", "loop", "--no-progress",
                    "-o", str(args.out / "local.parquet"), "--overwrite"], check=True)  # fmt: skip
    subprocess.run([python, "-m", "pendsweep.cli", "alpha", *sweep[:-2], "--direction", "loop", "--no-progress",
                    "-o", str(args.out / "emulated.parquet"), "--overwrite"], check=True)  # fmt: skip
    compare(args.out, nudges)


def relabel(unit):
    """A rig unit's label from its records by the current classifier (noisy; no re-simulation)."""
    import numpy as np

    from pendsweep.analysis.classify import classify_records
    from pendsweep.analysis.sections import section_scales
    from pendsweep.backends.status import Status
    from pendsweep.kernels import RECORD_COLUMNS
    from pendsweep.model.params import ModelParams

    records = unit[list(RECORD_COLUMNS)].to_numpy(dtype=np.float64)
    params = ModelParams.from_mapping({"fe": 2.5, "alpha": float(unit["alpha"].iloc[0])})
    status = Status(unit["status"].iloc[0])
    motion = classify_records(records, section_scales(records, params), status, None, noisy=True)
    return unit["motion"].map(lambda _: motion.label)


def compare(out: Path, nudges: int) -> None:
    """comparison.csv, the agreement lines and fig11a_rig.png (the three diagrams one above the other)."""
    import pandas as pd

    from pendsweep.canvas import new_figure
    from pendsweep.engine.results import read_results
    from pendsweep.figures.plotting import draw_bifurcation

    names = {"rig": "through the site, one session", "local": "in process", "emulated": "emulated system"}
    per_point = {}
    for name in names:
        rows = pd.read_parquet(out / f"{name}.parquet")
        if name == "rig":  # labelled by the classifier of the day (a rig's records alone decide them)
            rows["motion"] = rows.groupby(["direction", "point"], group_keys=False).apply(relabel)
        per_point[name] = rows.groupby(["direction", "alpha"]).agg(
            motion=("motion", "first"), theta_max=("theta_absmax", "max")
        )
    table = pd.concat(per_point, axis=1)
    table.columns = [f"{a}_{b}" for a, b in table.columns]
    table.to_csv(out / "comparison.csv")

    def family(label: str) -> str:
        return "periodic" if label.startswith("periodic") else label

    same = (table["rig_motion"].map(family) == table["local_motion"].map(family)).mean()
    close = ((table["rig_theta_max"] - table["local_theta_max"]).abs() < 0.05).mean()
    print(f"{nudges} nudges; motion family agrees with in process at {same:.0%} of points, "
          f"theta_max within 0.05 rad at {close:.0%}")  # fmt: skip
    for direction in ("up", "down"):
        branch = table.loc[direction].loc[10.0:]  # past the first point's own decay from the site's theta0
        onsets = {name: branch.index[branch[f"{name}_theta_max"] > 0.3].min() for name in names}
        periodic = {name: branch.index[branch[f"{name}_motion"].str.startswith("periodic")] for name in names}
        print(
            f"{direction}: swing > 0.3 rad from "
            + ", ".join(f"{n} {v:g} N" for n, v in onsets.items())
            + "; periodic from "
            + ", ".join(f"{n} {v.min():g} N" for n, v in periodic.items() if len(v))
        )
    fig = new_figure((9, 10))
    axes = fig.subplots(3, 1, sharex=True)
    for ax, (name, title) in zip(axes, names.items()):
        draw_bifurcation(ax, [read_results(out / f"{name}.parquet")])
        ax.set_title(f"Fig. 11(a), 0 -> 45 -> 0 N: {title}", fontsize=9)
    fig.savefig(out / "fig11a_rig.png", dpi=120, bbox_inches="tight")


if __name__ == "__main__":
    main()
