"""Two-parameter bifurcation curves and the hybrid loop's own orbits (issue 32)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from click.testing import CliRunner

from pendsweep.analysis.continuation import (
    FOLD,
    NEIMARK_SACKER,
    PERIOD_DOUBLING,
    Continuation,
    PendulumShooting,
    Settings,
)
from pendsweep.analysis.continuation import semi_trivial_section as rest_section
from pendsweep.analysis.continuation.curve_system import CurveProblem
from pendsweep.analysis.continuation.curves import CurveContinuation, curve_settings
from pendsweep.analysis.continuation.loop import LoopShooting, smoothed_backend
from pendsweep.analysis.continuation.tolerance import within_limit
from pendsweep.analysis.semi_trivial import hopf_floquet
from pendsweep.backends import make_backend
from pendsweep.cli import main
from pendsweep.model.params import TABLE_IV
from pendsweep.studies.hopf import alpha_hopf_analytic, fe_for_omega_hat
from test_continuation import Duffing

#: The smooth model of the continuation tests (b1 = b3 = 0), fe = 2.5 Hz.
SMOOTH = TABLE_IV.replace(b1=0.0, b3=0.0, fe=2.5)
#: Emulated period doubling of the semi-trivial solution at fe = 2.5 Hz [N] (docs/continuation.md).
PD_EMULATED = 16.0971804
#: Fig. 10's omega_hat range and the forcing frequencies at its ends [Hz].
FE_RANGE = (fe_for_omega_hat(SMOOTH, 0.88), fe_for_omega_hat(SMOOTH, 1.12))


def floquet_boundary(params):
    """pendsweep's Floquet boundary (`hopf_floquet`, 400 RK4 steps per period, bracketed to 1e-6 N)
    refined to 1e-13 N by brentq on the same log max|multiplier|, so the comparison is relative at the tip too."""
    from scipy.optimize import brentq

    from pendsweep.analysis.semi_trivial import floquet_multipliers

    coarse = hopf_floquet(params, steps=400)
    assert coarse["multiplier"] == pytest.approx(-1.0, abs=1e-5)

    def log_rho(alpha):
        return float(np.log(np.abs(floquet_multipliers(params.replace(alpha=alpha), 400)).max()))

    a = coarse["alpha_H"]
    return brentq(log_rho, a - 2e-6, a + 2e-6, xtol=1e-13)


def trace(problem, second, kind, x0, lam1, lam2, bounds1, bounds2, reference, **settings):
    """A curve of ``problem`` from ``(x0, lam1, lam2)`` (both ways)."""
    cp = CurveProblem(problem, second, kind, abs(bounds2[1] - bounds2[0]))
    cc = CurveContinuation(cp, bounds1, bounds2, curve_settings(**settings), names=(problem.parameter, second))
    return cc, cc.run(x0, lam1, lam2, reference)


@pytest.fixture(scope="module")
def pd_curve():
    """The semi-trivial solution's period-doubling curve in (alpha, fe) over Fig. 10's range."""
    problem = PendulumShooting(SMOOTH.replace(alpha=PD_EMULATED), "alpha", lam_scale=20.0)
    return trace(problem, "fe", PERIOD_DOUBLING, rest_section(SMOOTH), PD_EMULATED, 2.5, (0.0, 60.0), FE_RANGE, -1.0,
                 max_points=300, ds_max=0.1)  # fmt: skip


# -- the emulated system ---------------------------------------------------------------------
def test_semi_trivial_pd_curve_is_the_floquet_hopf_boundary(pd_curve):
    """Every curve point's alpha equals pendsweep's Floquet boundary at its fe to 1e-6 (measured <= 3e-8).

    The same RK4 steps per period on both sides (400); hopf_floquet brackets
    to 1e-6 N absolute. Eq. (12) is an averaging approximation: within 5 %
    here (measured: at most 3.9 %, at omega_hat = 0.88), not 1e-6.
    """
    _, curve = pd_curve
    assert curve.ends == ["range", "range"]
    fes = [p.lam2 for p in curve.points]
    assert min(fes) == pytest.approx(FE_RANGE[0], abs=1e-9) and max(fes) == pytest.approx(FE_RANGE[1], abs=1e-9)
    checked = 0
    for point in curve.points[:: max(1, len(curve.points) // 12)]:
        reference = floquet_boundary(SMOOTH.replace(fe=point.lam2))
        assert point.lam1 == pytest.approx(reference, rel=1e-6)
        assert alpha_hopf_analytic(SMOOTH.replace(fe=point.lam2)) == pytest.approx(point.lam1, rel=0.05)
        checked += 1
    assert checked >= 10


def test_pd_curve_turns_at_the_tongue_tip_and_changes_criticality(pd_curve):
    """The tongue: alpha is least at its tip near omega_hat = 1, where the PD turns from sub- to supercritical.

    Checked independently by the one-parameter continuation: on the c < 0
    side the doubled branch is born backwards and unstable (subcritical), on
    the c > 0 side forwards and stable.
    """
    _, curve = pd_curve
    events = {p.event: p for p in curve.points if p.event}
    tip, gpd = events["turn in alpha"], events["degenerate period doubling"]
    omega_hat_tip = SMOOTH.replace(fe=tip.lam2).omega_hat
    assert omega_hat_tip == pytest.approx(1.0, abs=0.01)
    assert tip.lam1 == pytest.approx(min(p.lam1 for p in curve.points), abs=1e-9)
    assert abs(gpd.normal_form) < 1e-2 * max(abs(p.normal_form) for p in curve.points)
    for side in (-1, 1):
        point = min((p for p in curve.points if np.sign(p.lam2 - gpd.lam2) == side and abs(p.lam2 - gpd.lam2) > 0.02),
                    key=lambda p: abs(p.lam2 - gpd.lam2))  # fmt: skip
        problem = PendulumShooting(SMOOTH.replace(fe=point.lam2, alpha=point.lam1), "alpha", lam_scale=2.0)
        result = Continuation(problem, (point.lam1 - 1.0, point.lam1 + 1.0), Settings(max_period=2)).run(
            point.x, point.lam1 - 1.0 if point.lam1 > 1.0 else point.lam1 * 0.5
        )
        (pd,) = [b for b in result.bifurcations if b.kind == PERIOD_DOUBLING and b.branch == 0]
        doubled = result.branches[1].points[2:8]
        forwards = all(p.lam > pd.lam for p in doubled)
        stable = all(p.stable for p in doubled)
        assert forwards == stable == (point.normal_form > 0), (side, point.normal_form)


@pytest.mark.parametrize("fe", [2.05, 2.15, 2.3, 2.4, 2.5])
def test_pd_curve_crosses_the_one_parameter_continuation_at_its_period_doubling(pd_curve, fe):
    """Fixed fe: the curve's point (Newton at that fe) is the PD that `continue alpha` finds, to 1e-7 N."""
    cc, curve = pd_curve
    point = crossing(cc, curve, fe)
    problem = PendulumShooting(SMOOTH.replace(fe=fe), "alpha", lam_scale=10.0)
    lo = max(point.lam1 - 3.0, 0.0)
    result = Continuation(problem, (lo, point.lam1 + 3.0), Settings(max_period=1)).run(
        rest_section(SMOOTH.replace(fe=fe, alpha=lo)), lo
    )
    located = [b.lam for b in result.bifurcations if b.kind == PERIOD_DOUBLING]
    assert min(abs(v - point.lam1) for v in located) < 1e-7


def crossing(cc, curve, value):
    """The curve's point at second parameter ``value``: Newton at fixed ``value`` from the chord between the
    two consecutive points that bracket it (the first such pair along the curve that converges)."""
    points = curve.points
    for a, b in zip(points, points[1:]):
        if (a.lam2 - value) * (b.lam2 - value) > 0 or a.lam2 == b.lam2:
            continue
        t = (value - a.lam2) / (b.lam2 - a.lam2)
        try:
            return cc.start(a.x + t * (b.x - a.x), a.lam1 + t * (b.lam1 - a.lam1), value, a.critical)
        except Exception:  # noqa: BLE001 - another bracketing pair may converge
            continue
    raise AssertionError(f"no curve point brackets {value}")


class DuffingPlane(Duffing):
    """The forced Duffing oscillator of test_continuation with its forcing frequency as a second parameter."""

    parameter = "F"

    def at(self, parameter, value):
        assert parameter == "omega"
        other = DuffingPlane()
        other.omega = value
        return other

    def params_at(self, lam):
        return None

    def section(self, x):
        return x


def duffing_cusp(delta):
    """Harmonic balance: the fold pair of x'' + d x' + x + x^3 = F cos(w t) merges at w = (sqrt(3) d + sqrt(3 d^2 + 4)) / 2."""
    return (math.sqrt(3) * delta + math.sqrt(3 * delta**2 + 4)) / 2


@pytest.fixture(scope="module")
def duffing_folds():
    """Both folds of the Duffing S-curve at w = 1.1, located by `Continuation`, and each one's curve in (F, w)."""
    problem = DuffingPlane()
    result = Continuation(problem, (0.005, 0.3), Settings(ds=0.02, ds_max=0.05)).run(np.zeros(2), 0.005)
    folds = sorted((b for b in result.bifurcations if b.kind == FOLD), key=lambda b: b.lam)
    curves = [
        trace(problem, "omega", FOLD, b.x, b.lam, 1.1, (0.0, 0.4), (1.0, 1.3), 1.0, max_points=120, ds_max=0.05)
        for b in folds
    ]
    return folds, curves


def test_fold_curves_meet_at_a_cusp_where_harmonic_balance_puts_it(duffing_folds):
    """The two folds' curves run into one cusp at w = 1.0442 (harmonic balance; measured within 0.3 %)."""
    _, curves = duffing_folds
    cusps = [p for _, curve in curves for p in curve.points if p.event == "cusp"]
    assert cusps, [c.ends for _, c in curves]
    for cusp in cusps:
        assert cusp.lam2 == pytest.approx(duffing_cusp(Duffing.delta), rel=0.005)
    # both folds' curves reach the same cusp
    lo_curve, hi_curve = (c for _, c in curves)
    lo_cusp = [p for p in lo_curve.points if p.event == "cusp"][0]
    hi_cusp = [p for p in hi_curve.points if p.event == "cusp"][0]
    assert lo_cusp.lam1 == pytest.approx(hi_cusp.lam1, rel=1e-4) and lo_cusp.lam2 == pytest.approx(
        hi_cusp.lam2, rel=1e-5
    )


@pytest.mark.parametrize("omega", [1.06, 1.1, 1.15, 1.2, 1.25])
def test_fold_curve_crosses_the_one_parameter_continuation_at_its_folds(duffing_folds, omega):
    """Fixed w: the fold curve's points (Newton at that w) are the folds `Continuation` locates in F, to 1e-7."""
    _, curves = duffing_folds
    problem = DuffingPlane().at("omega", omega)
    result = Continuation(problem, (0.005, 0.4), Settings(ds=0.02, ds_max=0.05)).run(np.zeros(2), 0.005)
    located = sorted(b.lam for b in result.bifurcations if b.kind == FOLD)
    assert len(located) == 2
    found = sorted(crossing(cc, curve, omega).lam1 for cc, curve in curves)
    assert found == pytest.approx(located, abs=1e-7)


@pytest.fixture(scope="module")
def rotation_ns():
    """The rotation's Neimark-Sacker point near 36.5 N (docs/continuation.md), and its curve in (alpha, fe)."""
    from pendsweep.backends import EmulatedBackend

    params = TABLE_IV.replace(alpha=38.0, fe=2.5)
    backend = EmulatedBackend()
    run = backend.run_point(params, backend.initial_state(params, 0.0, 0.0, 0.1, 0.0), 600, 1)
    problem = PendulumShooting(params, "alpha", lam_scale=10.0)
    x0 = run.state[:4]
    result = Continuation(problem, (30.0, 38.0), Settings(max_period=1)).run(x0, 38.0)
    (ns,) = [b for b in result.bifurcations if b.kind == NEIMARK_SACKER]
    mu = ns.multipliers[ns.multipliers.imag > 1e-8]
    reference = complex(mu[np.argmin(np.abs(np.abs(mu) - 1))])
    cc, curve = trace(problem, "fe", NEIMARK_SACKER, ns.x, ns.lam, 2.5, (15.0, 45.0), (2.3, 2.6), reference,
                      max_points=80, ds_max=0.05)  # fmt: skip
    return ns, cc, curve


def test_rotation_neimark_sacker_is_at_36_49N_and_passes_a_1_4_resonance(rotation_ns):
    """The torus point of docs/continuation.md; along its curve the pair's angle passes pi/2 (1:4) near 2.39 Hz."""
    ns, _, curve = rotation_ns
    assert ns.lam == pytest.approx(36.49, abs=0.01)
    assert len(curve.points) > 10
    for p in curve.points:
        assert abs(p.critical) == pytest.approx(1.0, abs=1e-8) and abs(p.critical.imag) > 1e-3
    (r4,) = [p for p in curve.points if p.event == "1:4 resonance"]
    assert abs(r4.critical.real) < 1e-6 and 2.3 < r4.lam2 < 2.4


@pytest.mark.parametrize("fe", [2.36, 2.42, 2.46, 2.5, 2.54])
def test_ns_curve_crosses_the_one_parameter_continuation_at_its_torus_point(rotation_ns, fe):
    """Fixed fe: the curve's NS point is where `Continuation`'s own NS test locates it, to 1e-6 N."""
    _, cc, curve = rotation_ns
    point = crossing(cc, curve, fe)
    problem = PendulumShooting(TABLE_IV.replace(fe=fe, alpha=point.lam1), "alpha", lam_scale=4.0)
    result = Continuation(problem, (point.lam1 - 2.0, point.lam1 + 2.0), Settings(max_period=1)).run(
        point.x, point.lam1
    )
    located = [b.lam for b in result.bifurcations if b.kind == NEIMARK_SACKER]
    assert located and min(abs(v - point.lam1) for v in located) < 1e-6


# -- the hybrid loop --------------------------------------------------------------------------
def loop_pd(dt, window=(15.0, 16.8), **options):
    """The hybrid loop's period doubling of the semi-trivial solution at fe = 2.5 Hz [N], looked for in ``window``."""
    backend = smoothed_backend(make_backend("substructured", dt=dt, **options))
    lo, hi = window
    problem = LoopShooting(backend, SMOOTH.replace(alpha=lo), "alpha", lam_scale=hi - lo)
    x0 = problem.from_section(rest_section(SMOOTH.replace(alpha=lo)))
    result = Continuation(problem, window, Settings(max_period=1)).run(x0, lo)
    (pd,) = [b for b in result.bifurcations if b.kind == PERIOD_DOUBLING]
    return pd, problem


IDEAL = dict(actuator="ideal", predictor_order=-1, harmonic3=0.0, harmonic5=0.0, harmonic7=0.0, physics_substeps=1)


def test_ideal_loop_converges_to_the_emulated_pd_at_first_order_in_dt():
    """tau = 0, no prediction, ideal actuator: the force is held over one tick, an O(dt) error.

    Measured shifts -0.0286, -0.0137, -0.0067 N at dt = 2, 1, 0.5 ms: ratios 2.09 and 2.04.
    """
    shifts = [loop_pd(dt, **IDEAL)[0].lam - PD_EMULATED for dt in (2e-3, 1e-3, 5e-4)]
    assert all(s < 0 for s in shifts)
    assert shifts[0] / shifts[1] == pytest.approx(2.0, rel=0.1)
    assert shifts[1] / shifts[2] == pytest.approx(2.0, rel=0.1)


@pytest.fixture(scope="module")
def default_rig_pd():
    return loop_pd(1e-3)


def test_default_rig_pd_and_the_simulated_growth_of_a_small_swing(default_rig_pd):
    """At the paper's 18 ms with first-order prediction the PD is ~3 % below 16.097 N. A small swing on the
    loop's semi-trivial orbit, simulated by the sweep kernel (held signum, noise off), decays 0.3 N below it
    and grows 0.3 N above it, at the log-rate of the continued orbit's largest multiplier (to 15 %; below,
    the pendulum's pair is complex and the swing beats, so its log-envelope is fitted over 3000 periods)."""
    pd, problem = default_rig_pd
    assert 15.4 < pd.lam < 15.8
    backend = make_backend(
        "substructured", force_noise=0.0, lvdt_noise=0.0, encoder_resolution=0.0, lvdt_resolution=0.0
    )
    for offset, periods in ((-0.3, 3000), (0.3, 150)):
        alpha = pd.lam + offset
        params = SMOOTH.replace(alpha=alpha)
        orbit = Continuation(problem, (alpha - 0.01, alpha + 0.01), Settings(max_period=1)).start(
            _scaled(problem), problem.from_section(rest_section(params)), alpha
        )
        state = problem.full_state(orbit.x)
        state[2] = 1e-7  # a small swing on the loop's own semi-trivial orbit
        envelope = _theta_envelope(backend.run_point(params, state, 0, periods))
        # the linear regime: after the first 20 periods (the other modes' transient), below 1e-3 rad
        window = np.flatnonzero((np.arange(periods) >= 20) & (envelope < 1e-3))
        window = window[window >= periods // 2] if offset < 0 else window
        rate = np.polyfit(window, np.log(envelope[window]), 1)[0]
        assert np.sign(rate) == np.sign(offset)
        assert rate == pytest.approx(math.log(float(np.abs(orbit.multipliers).max())), rel=0.15)


def _scaled(problem):
    from pendsweep.analysis.continuation.algebra import _Scaled

    return _Scaled(problem, Settings())


def _theta_envelope(run):
    from pendsweep.kernels import RECORD_COLUMNS

    return run.records[:, RECORD_COLUMNS.index("theta_absmax")]


def test_loop_is_continuous_in_the_delay_and_smooth_between_ticks():
    """The held command's switch is resolved exactly: the loop's PD is continuous in the transport delay and
    smooth while the delay stays within one tick, with a kink where the switch crosses a sampling instant
    (a whole number of ticks: the load cell's momentum sample then sees the switch one tick later).
    Measured one-sided slopes over 0.05 ms: -39 and -47 N/s at 9.5 ms; -126 and +30 N/s at 10 ms."""
    pd = {
        t: loop_pd(1e-3, transport_delay=t, window=(15.45, 15.75))[0].lam
        for t in (9.45e-3, 9.5e-3, 9.55e-3, 9.95e-3, 10e-3, 10.05e-3)
    }

    def slopes(t):
        return (pd[t] - pd[round(t - 5e-5, 8)]) / 5e-5, (pd[round(t + 5e-5, 8)] - pd[t]) / 5e-5

    left, right = slopes(9.5e-3)
    assert right == pytest.approx(left, rel=0.3)  # the curvature of a smooth curve over 0.05 ms
    left, right = slopes(10e-3)
    assert left < 0 < right
    assert abs(loop_pd(1e-3, transport_delay=10e-3 + 1e-9, window=(15.45, 15.75))[0].lam - pd[10e-3]) < 1e-5


def test_hermite_actuator_is_smooth_in_the_delay_across_a_substep():
    """The delay actuator evaluates the command's cubic on its own segment at every RK4 stage: the PD's
    one-sided slopes either side of 9.5 ms (a substep boundary, the knot inside a substep around it) agree."""
    pd = {
        t: loop_pd(1e-3, actuator="delay", transport_delay=t, predictor_order=-1, window=(15.3, 16.0))[0].lam
        for t in (9.45e-3, 9.5e-3, 9.55e-3)
    }
    left, right = (pd[9.5e-3] - pd[9.45e-3]) / 5e-5, (pd[9.55e-3] - pd[9.5e-3]) / 5e-5
    assert right == pytest.approx(left, rel=0.3)


def test_within_limit_interpolates_the_first_exit():
    delays = np.array([0.0, 0.01, 0.02, 0.03])
    assert within_limit(delays, np.array([0.0, -0.005, -0.015, -0.02]), 0.01) == pytest.approx(0.015)
    assert within_limit(delays, np.array([0.0, 0.001, 0.002, 0.003]), 0.01) == pytest.approx(0.03)
    assert within_limit(delays, np.array([0.02, 0.0, 0.0, 0.0]), 0.01) is None


# -- the commands -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def continuation_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("curve") / "c.json"
    result = CliRunner().invoke(
        main, ["continue", "alpha", "--from", "10", "--to", "25", "--set", "b1=0", "--set", "b3=0",
               "--max-period", "1", "-o", str(path)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    return path


def test_cli_curve_writes_rows_with_configuration_and_resumes(continuation_file, tmp_path, monkeypatch):
    """An interrupted curve resumes from its checkpoint to the same rows as an uninterrupted run."""
    from pendsweep.analysis.continuation import curves as curves_module
    from pendsweep.engine.results import read_results

    args = ["curve", str(continuation_file), "--second", "fe", "--from", "2.4", "--to", "2.6", "--max-points", "30"]
    whole = tmp_path / "whole.parquet"
    result = CliRunner().invoke(main, args + ["-o", str(whole)])
    assert result.exit_code == 0, result.output
    rows, meta = read_results(whole)
    assert meta["kind"] == "curve" and meta["complete"] and meta["config"]["second"] == "fe"
    assert {"alpha", "fe", "omega_hat", "critical_re", "normal_form", "event", "multipliers_re"} <= set(rows)
    assert np.allclose(rows["critical_re"], -1.0, atol=1e-8)

    cut = tmp_path / "cut.parquet"
    original = curves_module.CurveContinuation.march
    calls = {"n": 0}

    def interrupted(self, start, on_point=None, budget=None):
        def failing(point):  # a Ctrl-C after the 14th accepted point
            calls["n"] += 1
            if calls["n"] > 14:
                raise KeyboardInterrupt
            on_point(point)

        return original(self, start, on_point=failing, budget=budget)

    monkeypatch.setattr(curves_module.CurveContinuation, "march", interrupted)
    CliRunner().invoke(main, args + ["-o", str(cut)])
    partial, meta = read_results(cut)
    assert not meta["complete"] and 10 <= len(partial) < len(rows)
    monkeypatch.setattr(curves_module.CurveContinuation, "march", original)
    result = CliRunner().invoke(main, args + ["-o", str(cut), "--resume"])
    assert result.exit_code == 0, result.output
    resumed, meta = read_results(cut)
    assert meta["complete"] and len(resumed) == len(rows)
    assert np.allclose(resumed["alpha"], rows["alpha"], rtol=1e-8) and np.allclose(resumed["fe"], rows["fe"], rtol=1e-9)


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--second", "nope", "--from", "2", "--to", "3"], "--second 'nope'"),
        (["--second", "alpha", "--from", "2", "--to", "3"], "continuation's own parameter"),
        (["--second", "fe", "--from", "2.6", "--to", "3"], "outside --from/--to"),
        (["--second", "fe", "--from", "2", "--to", "3", "--bifurcation", "7"], "--bifurcation 7"),
        (["--second", "transport_delay", "--from", "0", "--to", "0.03"], "substructured"),
    ],
)
def test_cli_curve_bad_input_exits_2(continuation_file, extra, needle):
    result = CliRunner().invoke(main, ["curve", str(continuation_file), *extra])
    assert result.exit_code == 2, result.output
    assert needle in result.output and "Traceback" not in result.output


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--orders", "1,9"], "--orders"),
        (["--within", "2"], "--within"),
        (["--delay-from", "0.02", "--delay-to", "0.01"], "--delay-from"),
        (["-B", "transport_delay=0.01"], "the study sets it"),
        (["-B", "rig=tcp://127.0.0.1:1"], "remote rig"),
    ],
)
def test_cli_tolerance_bad_input_exits_2(continuation_file, extra, needle):
    result = CliRunner().invoke(main, ["tolerance", str(continuation_file), *extra])
    assert result.exit_code == 2, result.output
    assert needle in result.output and "Traceback" not in result.output


def test_cli_continue_substructured_records_its_smoothing(tmp_path):
    """`continue --backend substructured`: the document says what was switched off; the overlay re-integrates it."""
    from pendsweep.analysis.continuation.run import read_json

    path = tmp_path / "h.json"
    result = CliRunner().invoke(
        main, ["continue", "alpha", "--from", "15.3", "--to", "15.9", "--set", "b1=0", "--set", "b3=0",
               "--backend", "substructured", "--max-period", "1", "-o", str(path), "--plot", str(tmp_path / "h.png")],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    doc = read_json(path)
    smoothing = doc["config"]["smoothing"]
    assert set(smoothing["switched_off"]) == {"force_noise", "lvdt_noise", "encoder_resolution", "lvdt_resolution"}
    assert doc["bifurcations"][0]["type"] == PERIOD_DOUBLING
    assert len(doc["bifurcations"][0]["state"]) == len(doc["branches"][0]["points"][0]["state"])
    assert (tmp_path / "h.png").stat().st_size > 0


def test_remote_rig_cannot_be_continued():
    from pendsweep.errors import ConfigError

    with pytest.raises(ConfigError, match="remote rig"):
        smoothed_backend(dataclasses.replace(make_backend("substructured"), rig="tcp://127.0.0.1:5555"))


def test_cli_tolerance_pure_delay_shifts_grow_from_the_dt_limit(continuation_file, tmp_path):
    """A pure delay without prediction: at 0 ms the loop's PD is the O(dt) shift of the force hold (-0.085 %);
    the shift grows with the delay, within 1 % to a limit the metadata gives; every row records loop stability."""
    from pendsweep.engine.results import read_results

    out = tmp_path / "tol.parquet"
    result = CliRunner().invoke(
        main, ["tolerance", str(continuation_file), "-B", "actuator=delay", "--delay-from", "0", "--delay-to", "0.004",
               "--delay-step", "0.001", "--orders=-1", "-o", str(out)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    rows, meta = read_results(out)
    assert meta["kind"] == "tolerance" and meta["ends"] == {"-1": "range"}
    assert list(rows["transport_delay"]) == pytest.approx([0.0, 0.001, 0.002, 0.003, 0.004])
    assert rows["shift"].iloc[0] == pytest.approx(-0.00085, abs=2e-4)
    assert (np.diff(rows["shift"]) < 0).all() and rows["loop_stable"].all()
    limit = meta["limits"]["-1"]
    assert (limit is None) == (abs(rows["shift"].iloc[0]) > 0.01)
    assert "no prediction" in result.output


def test_within_spans_finds_every_interval_on_a_stable_loop():
    from pendsweep.analysis.continuation.tolerance import within_spans

    delays = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    shifts = np.array([0.03, 0.02, 0.0, 0.0, 0.02, 0.0])
    ok = np.array([True, True, True, True, True, False])
    spans = within_spans(delays, shifts, 0.01, ok)
    assert spans == [pytest.approx((1.5, 3.5))]
    assert within_spans(delays, np.zeros(6), 0.01, np.ones(6, bool)) == [(0.0, 5.0)]
