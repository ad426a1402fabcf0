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
from pendsweep.params import ENCODER_RESOLUTION, ModelParams
from pendsweep.site.opensees import run_example
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
