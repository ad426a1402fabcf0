"""OpenSees drives a pendsweep site: the paper's hybrid test with OpenSees as the numerical substructure.

OpenSees holds the numerical model of Eq. (3), the mass-spring-damper: a node
of mass M1 = M - M2 on a zeroLength element with an Elastic (K) and a Viscous
(C1 = C - C2) material, forced by F_e = alpha sin(2 pi fe t) through a Trig
time series. A genericClient element at the node is the physical substructure:
the pendulum on its platform (M2, C2), served by `pendsweep site`. The
integrator is AlphaOS, non-iterative, because an experimental element cannot
revert a step.

Run it (the site first, in another terminal or in the background; OpenSees
connects once, so wait until the site listens, about 2 s after it starts):

    pendsweep site --port 8090 --once -o site-log.parquet &
    pendsweep wait tcp://127.0.0.1:8090
    LD_LIBRARY_PATH=$(python -c "import importlib.util as u; print(u.find_spec('openseespylinux').submodule_search_locations[0] + '/lib')") \\
        python examples/opensees_pendulum_site.py --port 8090

It prints the pendulum's max |theta| over the last 20 periods from the site's
log and, with --compare, the emulated system's (Eq. (11)) at the same point.
openseespy's own BLAS lives in openseespylinux/lib, which the loader does not
find by itself: hence LD_LIBRARY_PATH.
"""

from __future__ import annotations

import argparse
import time


def steps_per_period(fe: float, dt: float = 1e-3) -> int:
    """Whole steps per forcing period nearest to ``dt`` (as pendsweep does): 455 at 2.2 Hz, 400 at 2.5 Hz."""
    return max(1, round(1.0 / (fe * dt)))


def build_model(ops, port: int, M: float = 10.9, C: float = 20.0, K: float = 1910.0, M2: float = 0.9,
                C2: float = 10.0, host: str = "127.0.0.1", alpha_os: float = 1.0) -> None:  # fmt: skip
    """The numerical substructure in OpenSees (``ops``), its genericClient at the site, the AlphaOS analysis.

    No load pattern yet: the caller adds the forcing (a Trig series at node 2).
    """
    ops.wipe()
    ops.model("basic", "-ndm", 1, "-ndf", 1)
    ops.node(1, 0.0)
    ops.node(2, 0.0, "-mass", M - M2)  # M1: the numerical part of the oscillator's mass
    ops.fix(1, 1)
    ops.uniaxialMaterial("Elastic", 1, K)
    ops.uniaxialMaterial("Viscous", 2, C - C2, 1.0)  # C1 = C - C2; the platform's C2 is on the rig
    ops.element("zeroLength", 1, 1, 2, "-mat", 1, 2, "-dir", 1, 1)
    ops.element("genericClient", 2, "-node", 2, "-dof", 1, "-server", port, host)
    ops.constraints("Plain")
    ops.numberer("Plain")
    ops.system("FullGeneral")
    ops.algorithm("Linear")
    ops.integrator("AlphaOS", alpha_os)  # alpha = 1: no numerical damping; 2/3 to 1 accepted
    ops.analysis("Transient")


def build_and_run(port: int, alpha: float, fe: float, periods: int, steps_per_period: int,
                  host: str = "127.0.0.1", alpha_os: float = 1.0, **model: float) -> tuple[int, float]:  # fmt: skip
    """Build the numerical substructure in OpenSees, run ``periods`` forcing periods; (status, wall seconds)."""
    import openseespy.opensees as ops

    dt = 1.0 / (fe * steps_per_period)
    build_model(ops, port, host=host, alpha_os=alpha_os, **model)
    ops.timeSeries("Trig", 1, 0.0, 1e6, 1.0 / fe, "-factor", alpha)
    ops.pattern("Plain", 1, 1)
    ops.load(2, 1.0)
    start = time.perf_counter()
    status = ops.analyze(periods * steps_per_period, dt)
    wall = time.perf_counter() - start
    ops.wipe()  # deletes the genericClient, which sends die to the site
    return status, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, default=8090)
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--alpha", type=float, default=5.0, help="forcing amplitude [N] (Fig. 9 PO: 5)")
    parser.add_argument("--fe", type=float, default=2.2, help="forcing frequency [Hz]")
    parser.add_argument("--periods", type=int, default=120)
    parser.add_argument("--steps-per-period", type=int, default=None, help="default: dt nearest 1 ms")
    parser.add_argument("--log", default="site-log.parquet", help="the site's -o file, read after the run")
    parser.add_argument("--alpha-os", type=float, default=1.0, help="AlphaOS's alpha, 2/3 to 1 (1: no damping)")
    parser.add_argument("--compare", action="store_true", help="also run the emulated system (pendsweep)")
    args = parser.parse_args()
    n = args.steps_per_period or steps_per_period(args.fe)
    status, wall = build_and_run(
        args.port, args.alpha, args.fe, args.periods, n, host=args.host, alpha_os=args.alpha_os
    )
    simulated = args.periods / args.fe
    print(
        f"OpenSees analyze status {status}; {simulated:.1f} s simulated in {wall:.2f} s ({simulated / wall:.1f}x real time)"
    )
    time.sleep(0.5)  # the site writes its log when the client has left
    try:
        import numpy as np
        import pyarrow.parquet as pq

        log = pq.read_table(args.log).to_pydict()
    except OSError:
        print(f"no site log at {args.log} (start the site with -o {args.log})")
        return
    t, theta = np.asarray(log["t"]), np.asarray(log["theta_true"])
    last = t > (args.periods - 20) / args.fe
    print(f"site: max |theta| over the last 20 periods {np.abs(theta[last]).max():.5f} rad")
    if args.compare:
        from pendsweep import make_backend
        from pendsweep.model.params import ModelParams

        params = ModelParams.from_mapping({"alpha": args.alpha, "fe": args.fe})
        backend = make_backend("emulated")
        run = backend.run_point(params, backend.initial_state(params, 0.0, 0.0, 0.1, 0.0), args.periods - 20, 20)
        print(f"emulated: max |theta| over the last 20 periods {np.nanmax(run.records[:, 1]):.5f} rad")


if __name__ == "__main__":
    main()
