"""Hopf boundary of the semi-trivial solution: Eq. (12), Floquet, simulation, scans."""

import math

import numpy as np
import pytest
from click.testing import CliRunner

from pendsweep.backends import make_backend
from pendsweep.cli import main
from pendsweep.engine.results import read_results
from pendsweep.errors import ConfigError, ResultsError
from pendsweep.model.params import TABLE_IV
from pendsweep.studies.hopf import (
    HopfConfig,
    alpha_hopf_analytic,
    fe_for_omega_hat,
    floquet_multipliers,
    hopf_floquet,
    hopf_simulate,
    run_hopf,
)

SMOOTH = TABLE_IV.replace(b1=0.0, b3=0.0)  # the model Eq. (12) and Floquet are exact for


def at(params, omega_hat):
    return params.replace(fe=fe_for_omega_hat(params, omega_hat))


def test_eq12_paper_value():
    # fe = 2.5 Hz, M = 10.9 kg, C = 20 kg/s, K = 1910 N/m: the 16.46 N.
    assert alpha_hopf_analytic(TABLE_IV.replace(fe=2.5)) == pytest.approx(16.46, rel=5e-3)


def test_floquet_paper_value_and_flip_multiplier():
    result = hopf_floquet(SMOOTH.replace(fe=2.5))
    assert result["alpha_H"] == pytest.approx(16.1, rel=1e-2)
    # Principal parametric resonance: the pendulum swings at fe/2, multiplier -1.
    assert result["multiplier"] == pytest.approx(-1.0, abs=1e-4)


def test_floquet_agrees_with_eq12_across_tongue():
    for omega_hat in np.linspace(0.9, 1.1, 11):
        p = at(SMOOTH, omega_hat)
        assert hopf_floquet(p)["alpha_H"] == pytest.approx(alpha_hopf_analytic(p), rel=0.05), omega_hat


def test_unpumped_multipliers_are_damped_pendulum():
    # alpha = 0: theta'' + kp theta' + wp^2 theta = 0, multipliers exp((-kp/2 +- i wd) T).
    p = SMOOTH.replace(alpha=0.0)
    kp = p.b2 / (p.m * p.l**2)
    T = 1.0 / p.fe
    wd = math.sqrt(p.omega_p**2 - kp**2 / 4)
    mu = floquet_multipliers(p, steps=400)
    expected = np.exp((-kp / 2 + 1j * wd) * T)
    assert np.allclose(sorted(mu, key=np.imag), [expected.conjugate(), expected], rtol=0, atol=1e-9)


def test_floquet_monodromy_converges_at_fourth_order():
    p = SMOOTH.replace(fe=2.5, alpha=16.0)
    ref = floquet_multipliers(p, steps=4000)
    steps = np.array([20, 40, 80, 160])
    err = [np.abs(np.sort_complex(floquet_multipliers(p, int(n))) - np.sort_complex(ref)).max() for n in steps]
    slope = np.polyfit(np.log(steps), np.log(err), 1)[0]
    assert slope == pytest.approx(-4.0, abs=0.3)


@pytest.mark.parametrize("omega_hat", [0.92, 1.05, 1.1087])
def test_simulated_protocol_matches_floquet(omega_hat):
    p = at(SMOOTH, omega_hat)
    sim = hopf_simulate(p, make_backend("emulated"))
    floquet = hopf_floquet(p)["alpha_H"]
    assert sim["status"] == "ok"
    assert sim["alpha_H"] == pytest.approx(floquet, rel=0.02)
    assert sim["bracket_hi"] - sim["bracket_lo"] <= 0.1
    assert sim["growth_below"] <= 0 < sim["growth_above"]


def test_coulomb_friction_makes_boundary_depend_on_kick():
    # With b1 > 0 rest is locally stable: a smaller kick needs more forcing.
    p = TABLE_IV.replace(fe=2.5)
    backend = make_backend("emulated")
    small = hopf_simulate(p, backend, kick=0.003)["alpha_H"]
    large = hopf_simulate(p, backend, kick=0.01)["alpha_H"]
    assert small > large + 1.0


def test_rest_threshold_reaches_the_simulated_protocol():
    """The protocol's "at rest" is the run's rest_threshold: above pi rad the kicked pendulum never counts as growing."""
    p = at(SMOOTH, 1.05)
    backend = make_backend("emulated")
    assert hopf_simulate(p, backend, periods=60, alpha_max=40.0)["status"] == "ok"
    lenient = hopf_simulate(p, backend, periods=60, alpha_max=40.0, rest_threshold=4.0)
    assert lenient["status"] == "not-found" and lenient["growth_below"] <= 0.0
    assert HopfConfig(omega_hat=(1.0,), rest_threshold=4.0).to_dict()["rest_threshold"] == 4.0


def test_scan_rows_resume_and_reject_other_config(tmp_path):
    out = tmp_path / "hopf.parquet"
    config = HopfConfig(omega_hat=(0.95, 1.05), masses=(5.9, 10.9), methods=("analytic", "floquet"))
    df = run_hopf(config, out)
    assert len(df) == 8 and set(df["method"]) == {"analytic", "floquet"}
    assert (df["status"] == "ok").all()
    # A heavier oscillator (same C, K) raises the boundary below resonance.
    below = df[(df.point == 0) & (df.method == "floquet")].set_index("M")["alpha_H"]
    assert below[10.9] != below[5.9]
    stored, meta = read_results(out)
    assert meta["kind"] == "hopf" and len(stored) == 8
    assert run_hopf(config, out).equals(df)
    with pytest.raises(ResultsError):
        run_hopf(HopfConfig(omega_hat=(0.95,), methods=("analytic",)), out)


def test_scan_resumes_from_parts(tmp_path):
    out = tmp_path / "hopf.parquet"
    config = HopfConfig(omega_hat=(0.95, 1.0, 1.05), methods=("analytic",))
    full = run_hopf(config, out)
    # Simulate an interrupted run: only the parts of the first two points exist.
    from pendsweep.engine.results import ResultStore
    from pendsweep.studies.hopf import hopf_metadata, hopf_point

    out2 = tmp_path / "resumed.parquet"
    store = ResultStore(out2, hopf_metadata(config), ["mass_point", "point", "method"])
    for i in range(2):
        store.add(hopf_point(config, 0, i, "analytic"), f"0:{i}:analytic", [])
    store.flush()
    store.close()  # the interrupted run ends: its lock goes
    resumed = run_hopf(config, out2)
    assert resumed.equals(full)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(omega_hat=(-1.0,)),
        dict(omega_hat=(1.0,), methods=("guess",)),
        dict(omega_hat=(1.0,), model={"k3": 1e4}),
        dict(omega_hat=(1.0,), kick=0.0),
        dict(omega_hat=()),
    ],
)
def test_bad_config_is_a_clear_error(kwargs):
    with pytest.raises(ConfigError):
        HopfConfig(**kwargs)


def test_cli_single_value_prints_table(tmp_path):
    out = tmp_path / "h.parquet"
    res = CliRunner().invoke(
        main, ["hopf", "--what", "1.1087", "--method", "analytic,floquet", "-o", str(out), "--no-progress"]
    )
    assert res.exit_code == 0, res.output
    assert "floquet" in res.stdout and "16.089" in res.stdout and "16.448" in res.stdout
    df, _ = read_results(out)
    assert list(df["method"]) == ["analytic", "floquet"]


@pytest.mark.parametrize(
    "args",
    [
        ["--what", "0.9:1.1:x"],
        ["--what", "1", "--method", "nope"],
        ["--what", "1", "--set", "b1=-1"],
        ["--what", "1", "--set", "b1"],
        ["--what", "1", "--kick", "nan"],
    ],
)
def test_cli_bad_input_exits_2(tmp_path, args):
    res = CliRunner().invoke(main, ["hopf", *args, "-o", str(tmp_path / "h.parquet"), "--no-progress"])
    assert res.exit_code == 2
    assert "Traceback" not in res.output


def test_hopf_figures_quick(tmp_path):
    res = CliRunner().invoke(main, ["figures", "fig10a", "fig10b", "coexistence", "--quick", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert {p.name for p in tmp_path.glob("*.png")} == {"fig10a-quick.png", "fig10b-quick.png", "coexistence-quick.png"}


def test_the_vectorised_closed_form_is_the_scalar_one_point_by_point():
    """Eq. (12) in chunks of ANALYTIC_CHUNK points gives every point's scalar value, keys in order."""
    from pendsweep.studies.hopf import ANALYTIC_CHUNK, HopfConfig, alpha_hopf_analytic, hopf_analytic_rows

    n = ANALYTIC_CHUNK + 1001  # two chunks, the second short
    config = HopfConfig(omega_hat=tuple(np.linspace(0.8, 1.2, n)), masses=(10.9, 5.9), methods=("analytic",))
    units = config.units()
    assert units == [
        (0, 0, "analytic"),
        (0, ANALYTIC_CHUNK, "analytic"),
        (1, 0, "analytic"),
        (1, ANALYTIC_CHUNK, "analytic"),
    ]
    for j, first, _ in units:
        rows = hopf_analytic_rows(config, j, first).to_pandas()
        points = rows["point"].to_numpy()
        assert points[0] == first and np.all(np.diff(points) == 1)
        for k in (0, len(rows) // 2, len(rows) - 1):
            scalar = alpha_hopf_analytic(config.params_at(int(points[k]), j))
            assert rows["alpha_H"].iloc[k] == pytest.approx(scalar, rel=1e-13)
            assert rows["fe"].iloc[k] == pytest.approx(config.params_at(int(points[k]), j).fe, rel=1e-15)
