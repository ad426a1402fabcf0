"""Continuation of periodic orbits (issue 15): shooting, monodromy, Newton, bifurcations, CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from pendsweep.analysis.continuation import (
    BRANCH_POINT,
    FOLD,
    NEIMARK_SACKER,
    PERIOD_DOUBLING,
    Continuation,
    Evaluation,
    PendulumShooting,
    Settings,
    semi_trivial_section,
)
from pendsweep.analysis.continuation.algebra import _Scaled
from pendsweep.cli import main
from pendsweep.kernels._emulated import eq11_params
from pendsweep.kernels._rhs import eq11_rhs
from pendsweep.kernels._variational import damping_sign, eq11_jacobian
from pendsweep.model.params import TABLE_IV
from pendsweep.studies.hopf import hopf_floquet

#: b1 = b3 = 0, fe = 2.5 Hz, M = 10.9 kg: the issue's independent shooting measurement.
SMOOTH = TABLE_IV.replace(b1=0.0, b3=0.0, fe=2.5, alpha=10.0)


@pytest.fixture(scope="module")
def alpha_run():
    """Semi-trivial branch from 10 N, switched at its period doubling onto the period-2 branch, up to 46 N."""
    problem = PendulumShooting(SMOOTH, "alpha", lam_scale=36.0)
    cont = Continuation(problem, (10.0, 46.0), Settings())
    return cont.run(semi_trivial_section(SMOOTH), 10.0), problem


# -- the variational equations ----------------------------------------------------
@pytest.mark.parametrize("eps", [0.0, 0.05])
def test_jacobian_matches_central_differences_of_the_rhs(eps):
    """eq11_jacobian is the derivative of eq11_rhs (Eq. 11), checked by central differences at random states."""
    p = TABLE_IV.replace(k3=3e4)
    q = eq11_params(p.kernel_array(), False, False)
    rng = np.random.default_rng(7)

    def rhs(z, held):
        sgn, _ = damping_sign(z[3], eps, held)
        return np.array(eq11_rhs(tuple(z), (3.0, sgn), q))

    for _ in range(5):
        z = rng.normal(size=4) * np.array([0.02, 0.3, 1.0, 0.2])
        held = 1.0 if z[3] >= 0 else -1.0
        sgn, dsgn = damping_sign(z[3], eps, held)
        jac = np.array(eq11_jacobian(tuple(z), 3.0, sgn, dsgn, q)).reshape(4, 4)
        h = 1e-6 * np.array([0.02, 0.3, 1.0, 0.2])
        fd = np.column_stack(
            [(rhs(z + h[j] * e, held) - rhs(z - h[j] * e, held)) / (2 * h[j]) for j, e in enumerate(np.eye(4))]
        )
        assert np.allclose(jac, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_monodromy_is_the_derivative_of_the_discrete_map():
    """Variational RK4 = derivative of the RK4 map: central differences of P^2 agree to their own error."""
    problem = PendulumShooting(TABLE_IV.replace(alpha=25.0), "alpha", period=2, eps=0.05)
    x = np.array([-0.01, -0.4, 0.8, -4.0])
    phi = problem.evaluate(x, 25.0).jacobian
    h = 1e-6 * problem.scale
    fd = np.column_stack(
        [
            (
                problem.evaluate(x + h[j] * e, 25.0, tangent=False).residual
                - problem.evaluate(x - h[j] * e, 25.0, tangent=False).residual
            )
            / (2 * h[j])
            + e
            for j, e in enumerate(np.eye(4))
        ]
    )
    scaled_error = np.abs((phi - fd) * problem.scale[None, :] / problem.scale[:, None]).max()
    assert scaled_error < 1e-6


def test_liouville_product_of_multipliers(alpha_run):
    """prod(mu) = det(monodromy) = exp(integral of trace J over the period), same RK4 stages, to 1e-8."""
    result, problem = alpha_run
    branch = next(b for b in result.branches if b.period == 2)
    point = min(branch.points, key=lambda p: abs(p.lam - 30.0))
    ev = problem.with_period(2).evaluate(point.x, point.lam)
    product = np.prod(np.linalg.eigvals(ev.jacobian)).real
    assert product == pytest.approx(math.exp(ev.info.trace_integral), rel=1e-8)
    # The orbit is a large swing: the pendulum's state-dependent terms do enter the trace.
    linear_part = -2 * 0.4 * (SMOOTH.C / (SMOOTH.M + SMOOTH.m) + SMOOTH.b2 / (SMOOTH.m * SMOOTH.l**2))
    assert abs(ev.info.trace_integral - linear_part) > 1e-3


# -- Newton and the bifurcations of Eq. (11) ------------------------------------------
def test_newton_converges_quadratically(alpha_run):
    """Fixed-parameter Newton from a perturbed period-2 orbit: e_{k+1} ~ e_k^2 until rounding."""
    result, problem = alpha_run
    branch = next(b for b in result.branches if b.period == 2)
    point = min(branch.points, key=lambda p: abs(p.lam - 30.0))
    p2 = problem.with_period(2)
    scaled = _Scaled(p2, Settings())
    start = point.x + np.array([0.02, 0.1, 0.05, -0.3]) * p2.scale / 10
    _, ok, updates = Continuation(p2, (10, 46)).correct_fixed(scaled, start, point.lam)
    assert ok
    e = np.array(updates)
    big = e[e > 1e-8]
    assert big.size >= 3
    orders = np.log(big[1:]) / np.log(big[:-1])
    assert np.all(orders[1:] > 1.8), e  # the first step may still be outside the quadratic region
    assert np.all(big[1:] / big[:-1] ** 2 < 50.0)


def test_period_doubling_matches_the_floquet_boundary(alpha_run):
    """The semi-trivial solution period-doubles at the Mathieu-Floquet alpha_H (16.097 N) to 1e-4 relative."""
    result, problem = alpha_run
    pds = [b for b in result.bifurcations if b.kind == PERIOD_DOUBLING and b.branch == 0]
    assert len(pds) == 1
    floquet = hopf_floquet(SMOOTH, steps=problem.steps)
    assert floquet["alpha_H"] == pytest.approx(16.097, abs=1e-3)  # the issue's measurement
    assert pds[0].lam == pytest.approx(floquet["alpha_H"], rel=1e-4)
    assert np.min(np.abs(pds[0].multipliers + 1.0)) < 1e-6


def test_period_two_branch_supercritical_and_stable_to_46N(alpha_run):
    """Issue: the period-2 branch is supercritical, stable up to at least 46 N, max |mu| 0.94 at 46 N."""
    result, _ = alpha_run
    branch = next(b for b in result.branches if b.period == 2)
    lam = np.array([p.lam for p in branch.points])
    assert lam.min() == pytest.approx(16.097, abs=1e-3) and lam.max() == pytest.approx(46.0)
    assert np.all(np.diff(lam) > 0)  # born on the side where the semi-trivial solution is unstable
    assert all(p.stable for p in branch.points[1:])
    assert branch.points[-1].max_multiplier == pytest.approx(0.94, abs=0.005)
    assert not [b for b in result.bifurcations if b.branch != 0]


def test_period_doubling_in_fe_is_on_the_floquet_boundary():
    """Continued in fe at alpha = 17 N (steps per period fixed, dt drifts): hopf_floquet there gives 17 N."""
    params = SMOOTH.replace(alpha=17.0, fe=2.45)
    problem = PendulumShooting(params, "fe", lam_scale=0.15)
    result = Continuation(problem, (2.45, 2.6), Settings(max_period=1)).run(semi_trivial_section(params), 2.45)
    (pd,) = [b.lam for b in result.bifurcations if b.kind == PERIOD_DOUBLING]
    assert hopf_floquet(SMOOTH.replace(fe=pd), steps=problem.steps)["alpha_H"] == pytest.approx(17.0, rel=1e-4)


def test_mass_continuation_two_period_doublings():
    """Issue: in M at alpha = 17 N two period doublings with a stable period-2 branch between them."""
    params = SMOOTH.replace(alpha=17.0, M=2.0)
    cont = Continuation(PendulumShooting(params, "M", lam_scale=11.0), (2.0, 13.0), Settings(max_period=2))
    result = cont.run(semi_trivial_section(params), 2.0)
    pds = sorted(b.lam for b in result.bifurcations if b.kind == PERIOD_DOUBLING and b.branch == 0)
    assert len(pds) == 2
    (branch,) = [b for b in result.branches if b.period == 2]
    lam = [p.lam for p in branch.points]
    assert min(lam) == pytest.approx(pds[0]) and max(lam) == pytest.approx(pds[1])
    assert branch.ends[-1] == "reached its period doubling"
    assert all(p.stable for p in branch.points[1:-1])
    semi_trivial = result.branches[0].points
    inside = [p.stable for p in semi_trivial if pds[0] < p.lam < pds[1]]
    outside = [p.stable for p in semi_trivial if p.lam < pds[0] or p.lam > pds[1]]
    assert inside and not any(inside) and outside and all(outside)


# -- the paper's damping: Coulomb friction smoothed by tanh(w / eps) -------------------
def test_coulomb_fold_converges_in_eps_and_brackets_the_brute_force_sweep(tmp_path):
    """Table IV damping: the period-2 branch turns at a fold (rest stays stable), the same for every eps.

    The fold moves by less than 1e-3 N over eps = 1e-2 ... 1e-3 rad/s. A
    brute-force sweep with the paper's held signum (run_sweep, no smoothing),
    started on the period-2 swing, keeps swinging 0.05 N above the fold and
    comes to rest 0.05 N below it.
    """
    from pendsweep.backends import make_backend
    from pendsweep.studies.sweep import SweepConfig, run_sweep

    params = TABLE_IV.replace(alpha=18.0)
    backend = make_backend("emulated")
    x0 = backend.run_point(params, backend.initial_state(params, 0, 0, 0.1, 0), 600, 1).records[-1, 2:6].copy()
    folds = []
    for eps in (1e-2, 3e-3, 1e-3):
        problem = PendulumShooting(params, "alpha", period=2, eps=eps, lam_scale=4.0)
        result = Continuation(problem, (15.0, 19.0), Settings(max_period=2)).run(x0, 18.0)
        (fold,) = [b.lam for b in result.bifurcations if b.kind == FOLD]
        folds.append(fold)
        lower = [p for p in result.branches[0].points if p.lam < 17.0]
        assert any(p.stable for p in lower) and any(not p.stable for p in lower)  # swing and saddle meet there
    assert max(folds) - min(folds) < 1e-3
    assert not [b for b in result.bifurcations if b.kind == PERIOD_DOUBLING]  # rest never loses stability
    fold = folds[-1]
    swing = min((p for p in result.branches[0].points if p.stable), key=lambda p: abs(p.lam - fold - 0.05))
    values = (round(fold - 0.05, 4), round(fold + 0.05, 4))
    df = run_sweep(
        SweepConfig(
            "alpha",
            values,
            model={"fe": 2.5},
            mode="fresh",
            initial=tuple(swing.x),
            transient_periods=1000,
            record_periods=4,
        ),
        tmp_path / "bracket.parquet",
    )
    final = df.groupby("alpha")["theta_absmax"].max()
    assert final[values[0]] < 0.0013  # below the fold: at rest (one encoder pulse)
    assert final[values[1]] > 0.05  # above: still on the swing


def test_cli_continue_starts_from_a_sweep_result(tmp_path):
    """--start SWEEP.parquet takes the period from the recorded sections and Newton converges."""
    from pendsweep.studies.sweep import SweepConfig, run_sweep

    sweep = tmp_path / "s.parquet"
    run_sweep(
        SweepConfig(
            "alpha",
            (29.5, 30.0),
            model={"fe": 2.5, "b1": 0.0, "b3": 0.0},
            mode="fresh",
            transient_periods=400,
            record_periods=6,
        ),
        sweep,
    )
    out = tmp_path / "c.json"
    r = CliRunner().invoke(
        main,
        [
            "continue",
            "alpha",
            "--from",
            "28",
            "--to",
            "31",
            "--set",
            "b1=0",
            "--set",
            "b3=0",
            "--start",
            str(sweep),
            "--start-value",
            "30",
            "--json",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    assert doc["branches"][0]["period"] == 2 and doc["config"]["start_value"] == 30.0
    values = [p["value"] for p in doc["branches"][0]["points"]]
    assert min(values) == pytest.approx(28.0) and max(values) == pytest.approx(31.0)
    assert all(p["stable"] for p in doc["branches"][0]["points"])

    # `pendsweep plot` draws the branches over the sweep on the same axes; other parameters are refused.
    r = CliRunner().invoke(main, ["plot", str(sweep), str(out), "-o", str(tmp_path / "o.png")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "o.png").stat().st_size > 0
    other = json.loads(out.read_text())
    other["parameter"] = "M"
    (tmp_path / "m.json").write_text(json.dumps(other))
    r = CliRunner().invoke(main, ["plot", str(sweep), str(tmp_path / "m.json"), "-o", str(tmp_path / "p.png")])
    assert r.exit_code == 2 and "different parameters" in r.output


# -- a system with a known answer: the forced Duffing oscillator ----------------------
class Duffing:
    """x'' + delta x' + x + beta x^3 = F cos(w t), continued in F; stroboscopic map by RK4 (written here)."""

    delta, beta, omega, steps = 0.05, 1.0, 1.1, 128
    scale = np.ones(2)
    lam_scale = 1.0
    period = 1

    def with_period(self, period):
        raise NotImplementedError

    def subperiod_distance(self, x, info):
        return math.inf

    def image_distance(self, info, y):
        return math.inf

    def evaluate(self, x, F, tangent=True):
        d, b, w = self.delta, self.beta, self.omega
        h = 2 * math.pi / w / self.steps

        def f(t, u, v):
            return v, F * math.cos(w * t) - d * v - u - b * u**3

        def jac(u):
            return np.array([[0.0, 1.0], [-1.0 - 3 * b * u * u, -d]])

        u, v = float(x[0]), float(x[1])
        phi = np.eye(2)
        for k in range(self.steps):
            t = k * h
            a1 = f(t, u, v)
            a2 = f(t + h / 2, u + h / 2 * a1[0], v + h / 2 * a1[1])
            a3 = f(t + h / 2, u + h / 2 * a2[0], v + h / 2 * a2[1])
            a4 = f(t + h, u + h * a3[0], v + h * a3[1])
            if tangent:
                k1 = jac(u) @ phi
                k2 = jac(u + h / 2 * a1[0]) @ (phi + h / 2 * k1)
                k3 = jac(u + h / 2 * a2[0]) @ (phi + h / 2 * k2)
                k4 = jac(u + h * a3[0]) @ (phi + h * k3)
                phi = phi + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            u += h / 6 * (a1[0] + 2 * a2[0] + 2 * a3[0] + a4[0])
            v += h / 6 * (a1[1] + 2 * a2[1] + 2 * a3[1] + a4[1])
        return Evaluation(np.array([u, v]) - x, phi if tangent else None)


def duffing_fold_forces(delta, beta, omega):
    """Forcing amplitudes of the two folds from first-order harmonic balance.

    x = A cos(w t - phi): F^2 = A^2 [(1 - w^2 + 3/4 beta A^2)^2 + (delta w)^2]. With
    u = A^2, dF^2/du = 0 gives 3 b^2 u^2 + 4 a b u + a^2 + c = 0 (a = 1 - w^2,
    b = 3 beta / 4, c = (delta w)^2).
    """
    a, b, c = 1 - omega**2, 0.75 * beta, (delta * omega) ** 2
    roots = np.roots([3 * b * b, 4 * a * b, a * a + c])
    return sorted(math.sqrt(u * ((a + b * u) ** 2 + c)) for u in roots.real)


def test_duffing_folds_where_harmonic_balance_puts_them():
    """Folds of the hardening Duffing S-curve in F are found at the harmonic-balance values.

    First-order harmonic balance neglects the third harmonic, whose relative
    size here is about beta A^2 / (32 * 9 w^2) ~ 1e-3; measured: 0.31% and 0.13%, asserted 0.5%.
    """
    duffing = Duffing()
    f_lo, f_hi = duffing_fold_forces(duffing.delta, duffing.beta, duffing.omega)
    cont = Continuation(duffing, (0.005, 0.3), Settings(ds=0.02, ds_max=0.05))
    result = cont.run(np.zeros(2), 0.005)
    folds = sorted(b.lam for b in result.bifurcations if b.kind == FOLD)
    assert len(folds) == 2
    assert folds[0] == pytest.approx(f_lo, rel=0.005) and folds[1] == pytest.approx(f_hi, rel=0.005)
    # Between the folds the middle (saddle) branch is unstable: one real multiplier above 1.
    (branch,) = result.branches
    middle = [p for p in branch.points if p.lam < folds[1] and p.lam > folds[0] and p.tangent[-1] < 0]
    assert middle and all(not p.stable for p in middle)
    assert branch.ends == ["range", "range"]


# -- bifurcation verdicts on maps with known answers --------------------------------------
class _KnownMap:
    """A map with its fixed points in closed form, for the bifurcation tests (no integration)."""

    period = 1

    def __init__(self, lam_scale=1.0):
        self.lam_scale = lam_scale

    def with_period(self, period):
        raise NotImplementedError

    def subperiod_distance(self, x, info):
        return math.inf

    def image_distance(self, info, y):
        return math.inf


class NeutralSaddleThenTorus(_KnownMap):
    """x -> A(lam) x on R^4: real multipliers 26.82 and (0.7 + lam)/26.82 (product 1 at lam = 0.3: a
    neutral saddle, no bifurcation), and a complex pair of modulus 0.6 + 0.8 lam at angle 1.9 rad
    (crosses the unit circle at lam = 0.5: Neimark-Sacker)."""

    scale = np.ones(4)

    def evaluate(self, x, lam, tangent=True):
        r, phi = 0.6 + 0.8 * lam, 1.9
        a = np.zeros((4, 4))
        a[0, 0], a[1, 1] = 26.82, (0.7 + lam) / 26.82
        a[2:, 2:] = r * np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
        return Evaluation(a @ x - x, a)


def test_neutral_saddle_is_not_a_neimark_sacker_point():
    """Only the complex pair's crossing of the unit circle is a Neimark-Sacker point, at its exact value."""
    result = Continuation(NeutralSaddleThenTorus(), (0.0, 1.0)).run(np.zeros(4), 0.0)
    assert [b.kind for b in result.bifurcations] == [NEIMARK_SACKER]
    assert result.bifurcations[0].lam == pytest.approx(0.5, abs=1e-8)


class PitchforkOrFold(_KnownMap):
    """(a, b) -> (a + g(a, lam)/2, b + (lam - b)/2): b = lam on every branch, so the state moves with
    the parameter and the tangent's scaled parameter component is about 1/lam_scale.
    ``pitchfork``: g = lam a - a^3 (a = 0 crosses a = +-sqrt(lam) at lam = 0, the parameter does not turn);
    otherwise g = lam - a^2 (a = +-sqrt(lam) meet at a fold at lam = 0)."""

    scale = np.ones(2)

    def __init__(self, pitchfork, lam_scale):
        super().__init__(lam_scale)
        self.pitchfork = pitchfork

    def evaluate(self, x, lam, tangent=True):
        a, b = x
        g, g_a = (lam * a - a**3, lam - 3 * a * a) if self.pitchfork else (lam - a * a, -2 * a)
        return Evaluation(np.array([0.5 * g, 0.5 * (lam - b)]), np.array([[1 + 0.5 * g_a, 0.0], [0.0, 0.5]]))


@pytest.mark.parametrize("lam_scale", [2.0, 2000.0])
@pytest.mark.parametrize(
    "pitchfork, start, kind", [(True, (0.0, -0.5, -0.5), BRANCH_POINT), (False, (-0.5, 0.25, 0.25), FOLD)]
)
def test_fold_or_branch_point_does_not_depend_on_the_interval(lam_scale, pitchfork, start, kind):
    """A multiplier +1 is a fold only where the parameter turns back, whatever the parameter's scale."""
    result = Continuation(PitchforkOrFold(pitchfork, lam_scale), (-1.0, 1.0)).run(np.array(start[:2]), start[2])
    assert [b.kind for b in result.bifurcations] == [kind]
    # The corrector is singular at a branch point, so its location ends at a bracket end: measured
    # 8e-5 at lam_scale 2000 (4e-8 of the interval in scaled arclength); asserted 1e-4 of the interval.
    assert result.bifurcations[0].lam == pytest.approx(0.0, abs=2e-4)


def test_decreasing_interval_continues_downward_first():
    """--from 0.5 --to -1: the branch starts at 0.5 and its points run downward (as a negative ds would)."""
    result = Continuation(PitchforkOrFold(True, 2.0), (0.5, -1.0)).run(np.zeros(2) + [0.0, 0.5], 0.5)
    values = [p.lam for p in result.branches[0].points]
    assert values[0] == 0.5 and values[-1] == pytest.approx(-1.0)
    assert np.all(np.diff(values) < 0)


# -- the command line -------------------------------------------------------------------
def test_cli_continue_writes_the_issue_schema(tmp_path):
    out, png = tmp_path / "c.json", tmp_path / "c.png"
    r = CliRunner().invoke(
        main,
        [
            "continue",
            "alpha",
            "--from",
            "14",
            "--to",
            "20",
            "--set",
            "b1=0",
            "--set",
            "b3=0",
            "--json",
            str(out),
            "--plot",
            str(png),
            "--max-period",
            "2",
        ],
    )
    assert r.exit_code == 0, r.output
    assert "period-doubling at alpha = 16.0971" in r.output
    doc = json.loads(out.read_text())
    assert {"bifurcations", "branches", "config"} <= set(doc)
    assert set(doc["bifurcations"][0]) == {"type", "value", "branch", "period", "section", "multipliers"}
    assert [b["period"] for b in doc["branches"]] == [1, 2]
    point = doc["branches"][1]["points"][3]
    assert set(point) == {"value", "section", "multipliers", "max_multiplier", "stable"}
    assert len(point["section"]) == 4 and len(point["multipliers"]) == 4
    assert doc["config"]["model"]["b1"] == 0.0 and doc["config"]["steps_per_period"] == 400
    assert png.stat().st_size > 0

    # The period-2 orbit at 18 N as a start file gives the same branch (and its end at 20 N).
    start = tmp_path / "start.json"
    pick = min(doc["branches"][1]["points"], key=lambda p: abs(p["value"] - 18.0))
    start.write_text(json.dumps({"value": pick["value"], "section": pick["section"], "period": 2}))
    r = CliRunner().invoke(
        main,
        [
            "continue",
            "alpha",
            "--from",
            "17",
            "--to",
            "20",
            "--set",
            "b1=0",
            "--set",
            "b3=0",
            "--start",
            str(start),
            "--json",
            str(tmp_path / "d.json"),
        ],
    )
    assert r.exit_code == 0, r.output
    again = json.loads((tmp_path / "d.json").read_text())
    end = again["branches"][0]["points"][-1]
    assert end["value"] == pytest.approx(20.0)
    ref = doc["branches"][1]["points"][-1]
    assert np.allclose(end["section"], ref["section"], atol=1e-8)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--from", "10", "--to", "10"], "interval"),
        (["--from", "10", "--to", "20", "--eps", "-1"], "eps"),
        (["--from", "-1", "--to", "20"], "alpha = -1"),
        (["--from", "10", "--to", "20", "--start", "/nonexistent.json"], "no start file"),
        (["--from", "10", "--to", "20", "--set", "zeta=1"], "zeta"),
    ],
)
def test_cli_continue_bad_input_exits_2(args, needle):
    r = CliRunner().invoke(main, ["continue", "alpha", *args, "-o", "/tmp/never.json"])
    assert r.exit_code == 2, r.output
    assert needle in r.output and "Traceback" not in r.output


@pytest.mark.parametrize(
    "content, needle",
    [
        (b"\x89PNG\r\n\x1a\n\x00\xff", "UTF-8"),
        ('{"value": 30, "section": ["a", 0, 0, 0]}', 'section[0] = "a"'),
        ('{"value": "abc", "section": [0, 0, 0.5, 0]}', 'value = "abc"'),
        ('{"value": 30, "section": [0, 0, 0.5, 0], "period": "two"}', 'period = "two"'),
        ('{"value": 30, "section": [0, 0, 0.5, 0], "period": 2.7}', "period = 2.7 must be an integer >= 1"),
        ('{"value": 30, "section": 5}', "section = 5 must be a list of 4 numbers"),
    ],
)
def test_cli_continue_bad_start_file_exits_2(tmp_path, content, needle):
    start = tmp_path / "c.json"
    start.write_bytes(content if isinstance(content, bytes) else content.encode())
    r = CliRunner().invoke(
        main,
        ["continue", "alpha", "--from", "20", "--to", "40", "--start", str(start), "-o", str(tmp_path / "x.json")],
    )
    assert r.exit_code == 2, r.output
    assert needle in r.output and "Traceback" not in r.output and len(r.output.strip().splitlines()) <= 2


@pytest.mark.parametrize("option", [["--alpha", "99"], ["--set", "alpha=99"]])
def test_cli_continue_refuses_a_value_for_the_continued_parameter(tmp_path, option):
    r = CliRunner().invoke(
        main, ["continue", "alpha", "--from", "20", "--to", "40", *option, "-o", str(tmp_path / "x.json")]
    )
    assert r.exit_code == 2 and "continued parameter" in r.output, r.output
    assert not (tmp_path / "x.json").exists()


def test_cli_continue_warns_when_newton_leaves_the_start_orbit(tmp_path, alpha_run):
    """A period-2 section given without its period: Newton on P converges to rest, and says so on stderr."""
    result, _ = alpha_run
    swing = min(result.branches[1].points, key=lambda p: abs(p.lam - 30.0))
    start = tmp_path / "p2.json"
    start.write_text(json.dumps({"value": swing.lam, "section": list(swing.x)}))  # no "period": 1
    args = [
        "continue",
        "alpha",
        "--from",
        "29",
        "--to",
        "31",
        "--set",
        "b1=0",
        "--set",
        "b3=0",
        "--max-period",
        "1",
        "--start",
        str(start),
        "--json",
        str(tmp_path / "x.json"),
    ]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "x.json").read_text())
    assert doc["start_shift"] > 0.1 and "warning: Newton moved the start orbit" in r.stderr
    start.write_text(json.dumps({"value": swing.lam, "section": list(swing.x), "period": 2}))
    r = CliRunner().invoke(main, args)
    doc = json.loads((tmp_path / "x.json").read_text())
    assert r.exit_code == 0 and doc["start_shift"] < 1e-6 and "warning" not in r.stderr


def test_cli_continue_eps_0_with_coulomb_friction_prints_a_note(tmp_path):
    """--eps 0 drops b1 from the Jacobian: rest period-doubles where the friction-free pendulum does; a note says so."""
    r = CliRunner().invoke(
        main,
        [
            "continue",
            "alpha",
            "--from",
            "15",
            "--to",
            "17",
            "--eps",
            "0",
            "--max-period",
            "1",
            "--json",
            str(tmp_path / "x.json"),
        ],
    )
    assert r.exit_code == 0, r.output
    assert "note: --eps 0" in r.stderr and "b1" in r.stderr


def test_sweep_point_labelled_periodic_is_a_start_orbit(tmp_path):
    """A sweep point the classifier labels periodic-2 (Table IV damping, y drifting by ~1e-6 m over the record)
    gives period 2 both from its label and from the start's own repeat test."""
    from pendsweep.analysis.continuation.run import section_period, start_from_file
    from pendsweep.engine.results import read_results
    from pendsweep.model.params import ModelParams
    from pendsweep.studies.sweep import SweepConfig, run_sweep

    sweep = tmp_path / "s.parquet"
    run_sweep(SweepConfig("alpha", (25.0,)), sweep)
    df, _ = read_results(sweep)
    rows = df.sort_values("period")
    assert rows["motion"].iloc[0] == "periodic-2"
    sections = rows[["y_sec", "ydot_sec", "theta_sec", "thetadot_sec"]].to_numpy(dtype=float)
    assert section_period(sections, float(rows["y_absmax"].max()), ModelParams().replace(alpha=25.0)) == 2
    section, value, period = start_from_file(sweep, "alpha", 25.0)
    assert (value, period) == (25.0, 2) and np.allclose(section, sections[-1])


def test_cli_continue_runtime_failure_exits_1(tmp_path):
    """A start far from any orbit: Newton fails, a one-line message and exit status 1."""
    start = tmp_path / "bad.json"
    start.write_text(json.dumps({"value": 30.0, "section": [0.05, 2.0, 2.5, 40.0], "period": 1}))
    r = CliRunner().invoke(
        main,
        ["continue", "alpha", "--from", "20", "--to", "40", "--start", str(start), "-o", str(tmp_path / "x.json")],
    )
    assert r.exit_code == 1, r.output
    assert "Newton did not converge" in r.output


def test_fig11_continuation_quick(tmp_path):
    """The registry figure: sweeps, five continuations and the threshold panel, in quick form."""
    r = CliRunner().invoke(main, ["figures", "fig11_continuation", "--quick", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "fig11_continuation-quick.png").stat().st_size > 0
    docs = {p.name: json.loads(p.read_text()) for p in tmp_path.glob("*-continuation-*.json")}
    assert len(docs) == 5
    period_two = docs["fig11a-continuation-1-quick.json"]
    assert [b["type"] for b in period_two["bifurcations"]] == [FOLD]  # Table IV damping: a fold, no doubling
    assert period_two["bifurcations"][0]["value"] == pytest.approx(16.1526, abs=1e-3)
