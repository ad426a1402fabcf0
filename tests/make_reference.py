"""Regenerate ``tests/data/reference_v1.npz``: the numbers the refactors must not change.

Run once on the code *before* a refactor (``python tests/make_reference.py``);
``tests/test_reference.py`` then checks that the current code reproduces every
array bit for bit. Each case goes through a public entry point, so the
reference survives changes of kernel signatures.
"""

from pathlib import Path

import numpy as np

from pendsweep import FIG9_CO, FIG9_PO, TABLE_IV
from pendsweep.backends import make_backend
from pendsweep.kernels import driven_trace, pendulum_trace, substructured_replay
from pendsweep.studies.hopf import floquet_multipliers
from pendsweep.studies.sweep import SweepConfig, run_sweep

OUT = Path(__file__).with_name("data") / "reference_v1.npz"


def reference_arrays() -> dict[str, np.ndarray]:
    ref: dict[str, np.ndarray] = {}
    cols = ["theta_peak", "theta_absmax", "y_sec", "ydot_sec", "theta_sec", "thetadot_sec", "y_absmax", "rotations"]
    # Continue sweep (scalar kernel, carried state, kicks).
    cont = run_sweep(SweepConfig("alpha", (10.0, 14.0, 18.0, 22.0), transient_periods=6, record_periods=4))
    ref["continue"] = cont[cols].to_numpy(np.float64)
    # Fresh sweep (batched kernel), mixed steps per period (fe differs).
    fresh = run_sweep(
        SweepConfig(
            "fe", (2.2, 2.3, 2.5, 2.7), model={"alpha": 12.0}, mode="fresh", transient_periods=6, record_periods=4
        )
    )
    ref["fresh"] = fresh[cols].to_numpy(np.float64)
    # Scalar emulated point, signum per step and per stage, and its trace.
    for signum in ("step", "stage"):
        b = make_backend("emulated", signum=signum)
        run = b.run_point(FIG9_CO, b.initial_state(FIG9_CO, 0, 0, 0.3, 0), 5, 5)
        ref[f"emulated_{signum}"] = np.concatenate([run.records.ravel(), run.state])
    b = make_backend("emulated")
    ref["emulated_trace"] = b.trace(FIG9_PO, b.initial_state(FIG9_PO, 0, 0, 0.1, 0), 2, stride=7)[
        ["t", "y", "ydot", "theta", "thetadot"]
    ].to_numpy()
    # Substructured points: servo with prediction, delay actuator with filter, ideal.
    for name, opts in (
        ("sub_servo", {}),
        ("sub_delay_filter", {"actuator": "delay", "force_filter": True, "predictor_order": 2}),
        ("sub_ideal", {"actuator": "ideal", "predictor_order": -1}),
    ):
        sb = make_backend("substructured", **opts)
        run = sb.run_point(FIG9_PO, sb.initial_state(FIG9_PO, 0, 0, 0.2, 0), 3, 3)
        ref[name] = np.concatenate([run.records.ravel(), run.state])
    sb = make_backend("substructured")
    tr = sb.trace(FIG9_PO, sb.initial_state(FIG9_PO, 0, 0, 0.2, 0), 2, stride=5)
    ref["sub_trace"] = tr.to_numpy(np.float64)
    # Replays of measured records.
    p = TABLE_IV.kernel_array()
    out = np.empty((400, 2))
    pendulum_trace(np.array([1.0, 0.0]), p, 1e-3, 3, out)
    ref["pendulum_trace"] = out.copy()
    t = np.arange(500) * 1e-3
    f = 5.0 * np.sin(2 * np.pi * 2.2 * t)
    fh = 5.0 * np.sin(2 * np.pi * 2.2 * (t[:-1] + 5e-4))
    out4 = np.empty((500, 4))
    driven_trace(np.array([0.0, 0.0, 0.4, 0.0]), p, f, fh, 1.1, 1e-3, out4)
    ref["driven_trace"] = out4.copy()
    q = FIG9_PO
    cmd = np.zeros(500)
    cmdd = np.zeros(500)
    out4 = np.empty((499, 4))
    substructured_replay(
        np.array([0.0, 0.0, 0.4, 0.0]),
        q.kernel_array(),
        q.M1,
        q.C1,
        q.M2,
        q.C2,
        f,
        fh,
        1.0,
        1.0,
        0.012,
        1e-3,
        4,
        cmd,
        cmdd,
        0,
        out4,
    )
    ref["substructured_replay"] = np.concatenate([out4.ravel(), cmd, cmdd])
    # Floquet multipliers of the semi-trivial solution.
    mult = floquet_multipliers(TABLE_IV.replace(alpha=16.0, fe=2.5))
    ref["floquet"] = np.array([mult.real, mult.imag])
    return ref


if __name__ == "__main__":
    OUT.parent.mkdir(exist_ok=True)
    np.savez_compressed(OUT, **reference_arrays())
    print(f"wrote {OUT}")
