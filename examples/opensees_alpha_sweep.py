"""OpenSees sweeps the forcing through one continuous hybrid test: Fig. 11(a1) with the field's own numerical code.

The numerical substructure is examples/opensees_pendulum_site.py's (a node of
mass M1 on a zeroLength element, Elastic K and Viscous C1, AlphaOS), the
physical one a `pendsweep site`. Inside ONE OpenSees analysis, through one
genericClient connection, the forcing amplitude alpha is stepped at forcing-
period boundaries (the Trig series restarts its amplitude at phase 0), with
`--transient` periods left to decay and `--record` periods recorded at every
value, as the paper did. The site's log is then turned into the sweep's rows
(`pendsweep.hybrid.log_rows.sweep_rows`: one row per recorded period, the motion
class judged within the record's own noise), written as a sweep result that
`pendsweep plot` reads, and drawn beside the emulated system's diagram and,
with `--client ROWS.parquet`, pendsweep's own client's (`pendsweep alpha
--mode continue -B rig=...`).

Run it (the site first; `pendsweep wait` returns once the site listens, as
OpenSees's genericClient tries to connect only once):

    pendsweep site --port 8090 --once -o site-log.parquet &
    pendsweep wait tcp://127.0.0.1:8090
    LD_LIBRARY_PATH=$(python -c "import importlib.util as u; print(u.find_spec('openseespylinux').submodule_search_locations[0] + '/lib')") \\
        python examples/opensees_alpha_sweep.py --port 8090 --from 0 --to 45 --step 0.5 \\
        --log site-log.parquet -o opensees-alpha.parquet --plot opensees-alpha.png
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from opensees_pendulum_site import build_model, steps_per_period  # the same model, beside this script


def sweep_alpha(port: int, values: list[float], fe: float, transient: int, record: int, steps: int,
                host: str = "127.0.0.1", **model: float) -> tuple[int, float]:  # fmt: skip
    """One OpenSees analysis stepping alpha through ``values``; (analyze status, wall seconds).

    The model is examples/opensees_pendulum_site.py's. Every value runs
    ``transient + record`` forcing periods of ``steps`` steps; its load
    pattern replaces the last one at a period boundary, where the forcing's
    phase is 0, so the force is continuous across the step.
    """
    import openseespy.opensees as ops

    dt = 1.0 / (fe * steps)
    build_model(ops, port, host=host, **model)
    start = time.perf_counter()
    status = 0
    for tag, alpha in enumerate(values, start=1):
        if tag > 1:
            ops.remove("loadPattern", tag - 1)
        ops.timeSeries("Trig", tag, 0.0, 1e9, 1.0 / fe, "-factor", alpha)  # sin(2 pi fe t): phase 0 at every boundary
        ops.pattern("Plain", tag, tag)
        ops.load(2, 1.0)
        status = ops.analyze((transient + record) * steps, dt)
        if status != 0:
            break
    wall = time.perf_counter() - start
    ops.wipe()  # deletes the genericClient, which sends die to the site
    return status, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, default=8090)
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--from", dest="start", type=float, default=0.0, help="first alpha [N]")
    parser.add_argument("--to", dest="stop", type=float, default=45.0, help="last alpha [N]")
    parser.add_argument("--step", type=float, default=0.5, help="alpha step [N]")
    parser.add_argument("--fe", type=float, default=2.5, help="forcing frequency [Hz]")
    parser.add_argument("--transient", type=int, default=100, help="forcing periods left to decay per value")
    parser.add_argument("--record", type=int, default=20, help="forcing periods recorded per value")
    parser.add_argument("--log", default="site-log.parquet", help="the site's -o file, read after the run")
    parser.add_argument("-o", "--output", default="opensees-alpha.parquet", help="the sweep's rows (.parquet)")
    parser.add_argument("--plot", default=None, help="figure: OpenSees's diagram over the emulated system's")
    parser.add_argument("--client", default=None, help="rows of pendsweep's own client on the same rig, to draw too")
    args = parser.parse_args()
    import numpy as np

    count = int(round((args.stop - args.start) / args.step)) + 1
    values = [float(v) for v in np.round(args.start + args.step * np.arange(count), 12)]
    steps = steps_per_period(args.fe)
    status, wall = sweep_alpha(args.port, values, args.fe, args.transient, args.record, steps, host=args.host)
    simulated = len(values) * (args.transient + args.record) / args.fe
    print(f"OpenSees analyze status {status}; {len(values)} values, {simulated:.1f} s of test in {wall:.2f} s wall")
    from pendsweep.hybrid.log_rows import read_site_log, sweep_rows, write_sweep_rows
    from pendsweep.studies.sweep import SweepConfig

    log = read_site_log(Path(args.log), wait=5.0)  # the site writes its log when the client has left
    rows = sweep_rows(log, "alpha", values, args.fe, steps, args.transient, args.record, {"fe": args.fe})
    config = SweepConfig("alpha", tuple(values), {"fe": args.fe}, transient_periods=args.transient,
                         record_periods=args.record, kick=0.0, backend="substructured").to_dict()  # fmt: skip
    config["backend"] = "OpenSees (genericClient)"  # the numerical side's integrator; the rig is the site's
    write_sweep_rows(rows, Path(args.output), config, source=f"OpenSees genericClient; site log {args.log}")
    print(f"rows -> {args.output}")
    if args.plot:
        from pendsweep.figures.plotting import plot_files
        from pendsweep.studies.sweep import run_sweep

        # the emulated system at the same values (the kick of an in-process sweep leaves the semi-trivial branch)
        emulated = SweepConfig.from_dict({**config, "backend": "emulated", "backend_options": {}}).emulated_reference()
        reference = Path(args.output).with_name(Path(args.output).stem + "-emulated.parquet")
        run_sweep(emulated, reference, overwrite=True)
        files = [Path(args.output), reference] + ([Path(args.client)] if args.client else [])
        print(f"plot -> {plot_files(files, Path(args.plot), title='alpha swept inside one OpenSees analysis')}")


if __name__ == "__main__":
    main()
