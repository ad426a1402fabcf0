"""Stability of the substructured loop: section 2.4, Figs. 5-7, Table II, and the backend."""

import math

import numpy as np
import pytest
from click.testing import CliRunner

from pendsweep.analysis.stability import (
    SampledLoop,
    count_roots,
    critical_delay_from_roots,
    delay_margin,
    multipliers,
    phase_margins,
    rightmost_roots,
    sampled_delay_margin,
    servo_delay_margin,
    simulated_delay_margin,
    simulated_growth,
    stability_chart,
    switch_sequence,
    table_ii,
)
from pendsweep.analysis.stability._roots import _generator_eigenvalues
from pendsweep.cli import main
from pendsweep.model.params import (
    FIG5_LOOP,
    FIG7_LOOP,
    TABLE_II_FREQ_THEORY_PAPER,
    TABLE_II_LOOPS,
    TABLE_II_MODELS,
    LoopParams,
    ParameterError,
)

# -- Fig. 5, phase margins ------------------------------------------------------------------


def test_fig5_crossovers_margins_and_switches():
    slow, fast = phase_margins(FIG5_LOOP)
    assert slow.omega == pytest.approx(math.sqrt(200.0 / 3.0), rel=1e-12)  # 8.165 rad/s
    assert fast.omega == pytest.approx(math.sqrt(200.0), rel=1e-12)  # 14.14 rad/s
    assert fast.psi_deg == pytest.approx(180.0, abs=1e-9)
    assert slow.psi_deg == pytest.approx(332.5, abs=0.05)
    # The first switch is at the fast crossover (0.222 s); the paper prints 0.223 s and
    # attributes it to the slow one (its psi_2/omega_2 is actually 0.711 s).
    assert fast.tau == pytest.approx(0.2221, abs=5e-5) and fast.destabilising
    assert slow.tau == pytest.approx(0.7107, abs=5e-5) and not slow.destabilising
    m = delay_margin(FIG5_LOOP)
    assert (m.tau_star, m.omega_star) == (fast.tau, fast.omega)


def test_switch_bookkeeping_matches_argument_principle():
    """Unstable pairs from the switch sequence equal the roots counted in the right half-plane."""
    events = switch_sequence(FIG5_LOOP, 1.2)
    assert [round(t, 3) for t, _, _ in events[:3]] == [0.222, 0.666, 0.711]
    edges = [0.0] + [t for t, _, _ in events]
    for (lo, hi), (_, _, pairs_before) in zip(zip(edges[1:], edges[2:] + [1.2]), events):
        tau = 0.5 * (lo + hi)
        assert count_roots(FIG5_LOOP, tau, 1e-6, 5.0, 60.0) == 2 * pairs_before


# -- exact roots of the neutral DDE ------------------------------------------------------


@pytest.mark.parametrize("loop", [FIG5_LOOP, *TABLE_II_LOOPS], ids=["fig5", "p0.225", "p0.2925", "p0.455", "p0.6175"])
def test_exact_roots_agree_with_phase_margin(loop):
    m = delay_margin(loop)
    tau, omega = critical_delay_from_roots(loop, 1.5 * m.tau_star, grid=12)
    assert tau == pytest.approx(m.tau_star, rel=1e-3)
    assert omega == pytest.approx(m.omega_star, rel=1e-3)
    root = rightmost_roots(loop, m.tau_star, count=1)[0]
    assert abs(root.real) < 1e-9 and root.imag == pytest.approx(m.omega_star, rel=1e-9)


def test_roots_are_complete_in_a_box():
    loop, tau = TABLE_II_LOOPS[1], 0.05
    roots = rightmost_roots(loop, tau, count=50)
    inside = [r for r in roots if -40.0 < r.real < 5.0 and r.imag < 250.0]
    n_inside = sum(1 if r.imag == 0 else 2 for r in inside)  # conjugates are implied
    assert n_inside == count_roots(loop, tau, -40.0, 5.0, 250.0) > 2


def test_chebyshev_eigenvalues_converge_spectrally():
    loop, tau = TABLE_II_LOOPS[0], 0.08
    exact = rightmost_roots(loop, tau, count=1)[0]

    nodes = np.arange(4, 12)
    errors = np.array([np.min(np.abs(_generator_eigenvalues(loop, tau, n) - exact)) for n in nodes])
    # spectral (geometric) convergence: the error falls by a constant factor per node
    slope = np.polyfit(nodes, np.log10(errors), 1)[0]
    assert slope < -0.7 and np.all(np.diff(errors) < 0)


def test_neutral_case_is_detected():
    heavy = LoopParams(M1=4.0, C1=10.0, K=3000.0, ms=4.8, C2=10.0)  # p = 1.2
    m = delay_margin(heavy)
    assert m.verdict == "neutral_unstable" and m.tau_star is None
    assert "unstable for every delay" in m.reason
    # an infinite chain of roots in the right half-plane, tending to Re s = ln(p)/tau
    for tau in (0.01, 0.05):
        roots = rightmost_roots(heavy, tau, count=40)
        chain = roots[roots.imag > 20.0 * math.pi / tau]
        assert chain.size >= 3 and np.all(roots.real[: chain.size] > 0.0)
        assert chain.real == pytest.approx(math.log(1.2) / tau, rel=0.01)
    marginal = delay_margin(LoopParams(M1=4.0, C1=10.0, K=3000.0, ms=4.0, C2=10.0))
    assert marginal.verdict == "neutral_marginal" and marginal.tau_star is None


def test_stable_for_all_delays_has_no_crossover_and_no_unstable_root():
    loop = LoopParams.from_natural(10.0, 0.05, 0.09, 0.0)  # C2 = 0, p below 2 zeta sqrt(1 - zeta^2)
    m = delay_margin(loop)
    assert m.verdict == "stable_all_delays" and not m.crossings
    assert "stable for all delays" in m.reason
    for tau in (0.05, 0.3, 2.0):
        assert rightmost_roots(loop, tau, count=1)[0].real < 0.0


# -- Fig. 6, Fig. 7 and Table II ----------------------------------------------------------


def test_fig6_chart_limits():
    zeta = 0.05
    edge = 2.0 * zeta * math.sqrt(1.0 - zeta**2)  # C2 = 0: crossovers exist only above this p
    tau0, _ = stability_chart(10.0, zeta, 0.0, np.array([0.99 * edge, 1.01 * edge, 0.5, 0.999, 1.01]))
    assert np.isinf(tau0[0]) and np.isfinite(tau0[1]) and np.isnan(tau0[4])
    p = np.linspace(0.02, 0.99, 50)
    tau1, _ = stability_chart(10.0, zeta, 1.0, p)
    assert np.all(np.isfinite(tau1)) and np.all(np.diff(tau1) < 0)  # C2 = C1: finite everywhere, falls with p
    assert tau0[3] < 0.05 * tau0[2]  # tau_max -> 0 as p -> 1


def test_fig7_maximum_delay():
    assert delay_margin(FIG7_LOOP).tau_star == pytest.approx(0.009, abs=5e-5)  # caption: 0.009 s


def test_table_ii_theoretical_row():
    ours = [row[1] for row in table_ii()]
    assert ours == pytest.approx([31.1, 32.6, 37.1, 44.3], abs=0.05)
    # the paper's theoretical row is ours truncated to whole rad/s
    assert [math.floor(w) for w in ours] == list(TABLE_II_FREQ_THEORY_PAPER)


# -- the loop as the substructured backend runs it ----------------------------------------


@pytest.mark.parametrize("actuator, tau", [("servo", 0.0), ("servo", 0.09), ("delay", 0.09)])
def test_exact_sampled_loop_predicts_backend_growth(actuator, tau):
    loop, model = TABLE_II_LOOPS[0], TABLE_II_MODELS[0]
    mu = multipliers(loop, tau, SampledLoop(actuator=actuator))[0]
    sigma, omega = math.log(abs(mu)) / 1e-3, abs(np.angle(mu)) / 1e-3
    g = simulated_growth(model, tau, actuator=actuator, predictor_order=-1)
    assert g.sigma == pytest.approx(sigma, abs=0.03)
    assert g.omega == pytest.approx(omega, rel=0.01)


@pytest.mark.parametrize("index", [0, 1, 2, 3], ids=["p0.225", "p0.2925", "p0.455", "p0.6175"])
@pytest.mark.parametrize("actuator", ["delay", "servo"])
def test_simulated_critical_delay_matches_theory(index, actuator):
    """The paper's protocol on the backend: raise the delay until y* grows (Table II sets)."""
    loop, model = TABLE_II_LOOPS[index], TABLE_II_MODELS[index]
    if actuator == "delay":
        theory = delay_margin(loop)  # Eq. (9) with T = exp(-s tau)
    else:
        theory = servo_delay_margin(loop, 30.0, 0.7, hold=1e-3)  # T = exp(-s tau) G(s), ZOH
    exact = sampled_delay_margin(loop, SampledLoop(actuator=actuator), 0.2)
    sim = simulated_delay_margin(
        model, round(0.97 * exact.tau_star, 4), 0.02 * exact.tau_star, actuator=actuator, predictor_order=-1
    )
    assert sim.tau_star == pytest.approx(theory.tau_star, rel=0.05)
    assert sim.omega_star == pytest.approx(theory.omega_star, rel=0.05)
    # the backend resolves the delay to its 0.1 ms substep; sigma is interpolated over 2 % steps
    assert sim.tau_star == pytest.approx(exact.tau_star, rel=5e-3)


def test_compensation_raises_the_critical_delay_and_simulation_confirms():
    loop, model = TABLE_II_LOOPS[0], TABLE_II_MODELS[0]
    plain = SampledLoop(actuator="servo")
    predicted = SampledLoop(actuator="servo", predictor_order=1, predictor_points=5, tau_hat=0.018)
    none = sampled_delay_margin(loop, plain, 0.2).tau_star
    comp = sampled_delay_margin(loop, predicted, 0.2).tau_star
    assert comp > none + 0.005
    tau = 0.5 * (none + comp)
    assert simulated_growth(model, tau, actuator="servo", predictor_order=-1).sigma > 0.05
    assert (
        simulated_growth(model, tau, actuator="servo", predictor_order=1, predictor_points=5, tau_hat=0.018).sigma
        < -0.05
    )


def test_sampled_filter_and_predictors_match_backend():
    """Band-pass force filter, force prediction and y* prediction, all on at once."""
    loop, model = TABLE_II_LOOPS[0], TABLE_II_MODELS[0]
    cfg = SampledLoop(
        actuator="servo", predictor_order=1, tau_hat=0.018, filter_band=(0.5, 20.0), filter_frequency=model.fe
    )
    mu = multipliers(loop, 0.084, cfg)[0]
    g = simulated_growth(
        model,
        0.084,
        actuator="servo",
        predictor_order=1,
        tau_hat=0.018,
        force_filter=True,
        filter_low=0.5,
        filter_high=20.0,
    )
    assert g.sigma == pytest.approx(math.log(abs(mu)) / 1e-3, abs=0.03)
    assert g.omega == pytest.approx(abs(np.angle(mu)) / 1e-3, rel=0.005)


# -- CLI --------------------------------------------------------------------------------


def run(*args):
    return CliRunner().invoke(main, ["margin", *map(str, args)])


def test_cli_fig5_table():
    r = run("--M1", 20, "--C1", 20, "--K", 2000, "--ms", 10, "--C2", 20, "--tau-max", 0.05)
    assert r.exit_code == 0, r.output
    assert "14.1421" in r.output and "8.16497" in r.output and "332.47" in r.output
    assert "tau* = 0.222144 s" in r.output and "0.710688" in r.output


@pytest.mark.parametrize("option, value", [("--M1", 0), ("--ms", -1), ("--M1", "nan")])
def test_cli_rejects_non_positive_masses(option, value):
    r = run(option, value)
    assert r.exit_code == 2 and option.lstrip("-") in r.output


def test_cli_verdicts_and_table_ii(tmp_path):
    r = run("--ms", 0.5, "--C2", 0, "--C1", 20, "--actuator", "delay", "--tau-max", 0.02)
    assert r.exit_code == 0 and "stable for all delays" in r.output and "no gain crossover" in r.output
    r = run("--ms", 12, "--actuator", "delay", "--tau-max", 0.01)
    assert r.exit_code == 0 and "unstable for every delay" in r.output
    r = run("--M1", 20, "--C1", 20, "--K", 2000, "--ms", 10, "--C2", 20, "--tau-max", 0.01, "--roots-at", 0.3)
    assert r.exit_code == 0 and "spectral abscissa at tau = 0.3 s: +" in r.output  # beyond tau* = 0.222 s
    r = run("--table2")
    assert "31.11" in r.output and "32       34       40       45" in r.output
    r = run("--predictor", "1", "--tau-max", 0.01)
    assert r.exit_code == 2
    out = tmp_path / "bode.png"
    r = run("--M1", 20, "--C1", 20, "--K", 2000, "--ms", 10, "--C2", 20, "--tau-max", 0.01, "--plot", out)
    assert r.exit_code == 0 and out.stat().st_size > 10000


def test_parameter_errors_name_the_range():
    with pytest.raises(ParameterError, match=r"M1 = -1.0 kg is outside the accepted range \(0, inf\)"):
        LoopParams(M1=-1.0, C1=1.0, K=1.0, ms=1.0, C2=0.0)


def test_stability_figures_quick(tmp_path):
    from pendsweep.figures import make_figures

    written = make_figures(["fig5_margin", "fig6_chart", "stability_validation"], tmp_path, quick=True)
    assert [p.name for p in written] == ["fig5_margin.png", "fig6_chart.png", "stability_validation.png"]
    assert all(p.stat().st_size > 20000 for p in written)
