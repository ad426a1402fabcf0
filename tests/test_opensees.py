"""OpenSees's own genericClient against ``pendsweep site``: the paper's hybrid test with a real client.

OpenSees (openseespy, a test dependency) holds the numerical substructure of
Eq. (3): a node of mass M1 on a zeroLength element with Elastic K and Viscous
C1, forced through a Trig time series, integrated by AlphaOS; the site holds
the pendulum on its platform. The script is ``examples/opensees_pendulum_site.py``,
run as a user would, in its own process (openseespy's BLAS needs LD_LIBRARY_PATH).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from pendsweep import make_backend
from pendsweep.hybrid.opensees import run_example
from pendsweep.model.params import ENCODER_RESOLUTION, ModelParams
from site_helpers import SiteProcess

PERIODS = 120
RECORDED = 20


def hybrid_test(tmp_path: Path, alpha: float, fe: float, *site_args: str) -> tuple[dict, np.ndarray, str]:
    """Run OpenSees against a fresh site; (OpenSees result, site max |theta| per recorded period, site stderr)."""
    log = tmp_path / "site.parquet"
    site = SiteProcess("--once", "-o", str(log), "--set", f"fe={fe}", *site_args)
    result = run_example(site.port, alpha, fe, PERIODS)
    status, err = site.finish()
    assert status == 0, err
    table = pq.read_table(log)
    t, theta = table["t"].to_numpy(), table["theta_true"].to_numpy()
    period = np.floor(t * fe - 1e-9).astype(int)  # step k ends at t = k dt: period index of its interval
    last = period >= PERIODS - RECORDED
    swings = np.array([np.abs(theta[last & (period == p)]).max() for p in range(PERIODS - RECORDED, PERIODS)])
    return result, swings, err


def emulated_swings(alpha: float, fe: float) -> np.ndarray:
    params = ModelParams.from_mapping({"alpha": alpha, "fe": fe})
    backend = make_backend("emulated")
    run = backend.run_point(params, backend.initial_state(params, 0.0, 0.0, 0.1, 0.0), PERIODS - RECORDED, RECORDED)
    return run.records[:, 1]


@pytest.mark.parametrize("report_mass", ["true", "false"])
def test_fig9_periodic_orbit_through_opensees_matches_the_emulated_system(tmp_path, report_mass):
    """5 N at 2.2 Hz, 120 periods from theta0 = 0.1: max |theta| of the last 20 periods within 1 %."""
    result, swings, err = hybrid_test(tmp_path, 5.0, 2.2, "-B", f"report_mass={report_mass}")
    assert result["status"] == 0
    reference = emulated_swings(5.0, 2.2)
    assert reference.max() > 1.0  # a large periodic swing, not a trivial agreement at rest
    assert abs(swings.max() / reference.max() - 1) < 0.01, (swings.max(), reference.max())
    simulated = PERIODS / 2.2
    assert result["wall"] < simulated, f"{result['wall']:.1f} s wall for {simulated:.1f} s: slower than real time"
    assert "left after 54600 steps" in err


def test_opensees_at_2_5_hz_brings_the_pendulum_to_rest(tmp_path):
    """5 N at 2.5 Hz is below the Hopf boundary (Fig. 10): the semi-trivial solution, theta decays."""
    result, swings, _ = hybrid_test(tmp_path, 5.0, 2.5)
    assert result["status"] == 0
    assert swings.max() < ENCODER_RESOLUTION  # below one encoder pulse: at rest
    assert emulated_swings(5.0, 2.5).max() < ENCODER_RESOLUTION


def test_opensees_steps_alpha_inside_one_analysis_like_pendsweeps_own_client(tmp_path):
    """examples/opensees_alpha_sweep.py: alpha stepped through one OpenSees analysis and one site session; the
    site log turned into the sweep's rows agrees with pendsweep's own continuous client and the emulated system
    (max |theta| within 2 %: AlphaOS against the client's RK4 for the numerical model)."""
    import subprocess
    import sys

    from pendsweep.hybrid.opensees import EXAMPLE, opensees_env
    from pendsweep.studies.rig_sweep import RigWatch
    from pendsweep.studies.sweep import SweepConfig, run_sweep

    quiet = ("--set", "fe=2.5", "-B", "force_noise=0", "-B", "lvdt_noise=0")
    log = tmp_path / "site-log.parquet"
    site = SiteProcess("--once", *quiet, "-o", str(log))
    script = EXAMPLE.with_name("opensees_alpha_sweep.py")
    done = subprocess.run(
        [sys.executable, str(script), "--port", str(site.port), "--from", "28", "--to", "30", "--step", "2",
         "--transient", "40", "--record", "4", "--log", str(log), "-o", str(tmp_path / "os.parquet"),
         "--plot", str(tmp_path / "os.png")],
        env=opensees_env(), capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    status, err = site.finish()
    assert done.returncode == 0 and status == 0, done.stderr + err
    assert err.count("left after 35200 steps") == 1  # both values in one session: 2 x 44 periods x 400 steps
    opensees = pq.read_table(tmp_path / "os.parquet").to_pandas()
    assert opensees.groupby("alpha").size().tolist() == [4, 4]
    client_site = SiteProcess("--once", *quiet)
    config = SweepConfig("alpha", (28.0, 30.0), {"fe": 2.5}, transient_periods=40, record_periods=4, kick=0.0,
                         backend="substructured",
                         backend_options={"actuator": "ideal", "rig": f"tcp://127.0.0.1:{client_site.port}"})  # fmt: skip
    client = run_sweep(config, watch=RigWatch(reference=False, echo=lambda line: None))
    assert client_site.finish()[0] == 0
    emulated = pq.read_table(tmp_path / "os-emulated.parquet").to_pandas()
    ours = opensees.groupby("alpha")["theta_absmax"].max().to_numpy()
    assert ours.min() > 1.0  # the period-2 swing, not an agreement at rest
    for other in (client, emulated):
        np.testing.assert_allclose(ours, other.groupby("alpha")["theta_absmax"].max().to_numpy(), rtol=0.02)
    assert (tmp_path / "os.png").stat().st_size > 10_000
