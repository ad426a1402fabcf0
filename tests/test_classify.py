"""Motion classification: constructed cases known by construction, and the paper's Fig. 9."""

import math

import matplotlib.legend
import numpy as np
import pytest

from pendsweep.analysis.classify import (
    EXTEND_PERIODS,
    Evidence,
    classify_records,
    classify_run,
    closed_curve,
    lyapunov_estimate,
    two_trajectory_log_stretch,
)
from pendsweep.analysis.sections import NOISE_MAX, PERIODIC_TOL, section_period, section_scales
from pendsweep.backends import make_backend
from pendsweep.backends.status import Status
from pendsweep.kernels._layout import RECORD_INDEX as REC
from pendsweep.kernels._layout import SECTION_COLUMNS
from pendsweep.model.params import FIG9_CO, FIG9_PO
from pendsweep.studies.sweep import SweepConfig, run_sweep

UNIT = np.ones(4)  # constructed sections are already dimensionless
RECORD = 20


def records_from(states, rotations=0.0):
    """Per-period records whose section is ``states`` (k, 4) and envelope |theta| + 0.1."""
    states = np.asarray(states, dtype=float)
    rec = np.zeros((states.shape[0], 8))
    rec[:, SECTION_COLUMNS] = states
    rec[:, REC["theta_absmax"]] = np.abs(states[:, 2]) + 0.1
    rec[:, REC["y_absmax"]] = 1.0
    rec[:, REC["rotations"]] = rotations
    return rec


def orbit(advance, state, n):
    out = []
    for _ in range(n):
        state, _ = advance(state)
        out.append(state)
    return np.array(out)


def evidence_for(advance, first, last, periods=200):
    def make():
        return Evidence(orbit(advance, last, periods), two_trajectory_log_stretch(advance, first, periods, UNIT))

    return make


def classify_map(advance, start, burn_in=50):
    states = orbit(advance, np.asarray(start, dtype=float), burn_in + RECORD)[burn_in:]
    return classify_records(records_from(states), UNIT, Status.OK, evidence_for(advance, states[0], states[-1]))


def never():
    raise AssertionError("a periodic record must be decided without extending it")


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8])
def test_periodic_n_by_construction(n):
    rng = np.random.default_rng(n)
    cycle = rng.uniform(-1, 1, size=(n, 4))
    states = cycle[np.arange(RECORD) % n]
    assert classify_records(records_from(states), UNIT, Status.OK, never).label == f"periodic-{n}"


def test_quasi_periodic_two_incommensurate_frequencies():
    # theta(t) = a cos(w1 t) + b cos(w2 t), w2/w1 = golden ratio, sampled every 2 pi / w1.
    a, b, w2 = 0.3, 0.4, 2.0 * (1 + math.sqrt(5)) / 2
    turn = 2 * math.pi * (w2 / 2.0)  # phase advance of the w2 component per sample (w1 = 2)

    def advance(state):
        x, v = state[2] - a, state[3] / -w2  # b cos(phase), b sin(phase)
        c, s = math.cos(turn), math.sin(turn)
        x, v = c * x - s * v, s * x + c * v
        return np.array([0.0, 0.0, a + x, -w2 * v]), abs(a + x)

    motion = classify_map(advance, [0.0, 0.0, a + b, 0.0])
    assert motion.label == "quasi-periodic"
    assert abs(motion.lyapunov) < 3 * motion.lyapunov_err  # zero within its uncertainty


def test_closed_curve_rejects_clouds_and_strange_attractors():
    cloud = np.zeros((200, 4))
    cloud[:, 2:] = np.random.default_rng(0).normal(size=(200, 2))
    assert not closed_curve(cloud, UNIT)
    assert not closed_curve(orbit(henon, np.array([0.0, 0.0, 0.1, 0.1]), 300)[100:], UNIT)


def henon(state):
    x, y = state[2], state[3]
    nxt = np.array([0.0, 0.0, 1.0 - 1.4 * x * x + y, 0.3 * x])
    return nxt, abs(nxt[2])


def test_chaotic_henon_map_and_its_lyapunov_exponent():
    motion = classify_map(henon, [0.0, 0.0, 0.1, 0.1])
    assert motion.label == "chaotic"
    # The Henon map's largest exponent is 0.419 per iteration.
    samples = two_trajectory_log_stretch(henon, np.array([0.0, 0.0, 0.1, 0.1]), 3000, UNIT)[100:]
    lle, err = lyapunov_estimate(samples)
    assert lle == pytest.approx(0.419, abs=max(3 * err, 0.01))


def test_converging_spiral_is_transient():
    r, turn = 0.97, 0.3

    def advance(state):
        c, s = math.cos(turn), math.sin(turn)
        x, v = state[2], state[3]
        return np.array([0.0, 0.0, r * (c * x - s * v), r * (s * x + c * v)]), abs(x) + 0.1

    motion = classify_map(advance, [0.0, 0.0, 1.0, 0.0], burn_in=0)
    assert motion.label == "transient"
    assert motion.lyapunov == pytest.approx(math.log(r), abs=1e-9)


def test_rest_rotation_and_failure():
    rest = records_from(np.zeros((RECORD, 4)))
    rest[:, 1] = 1e-4
    assert classify_records(rest, UNIT, Status.OK, never).label == "semi-trivial"
    cycle = np.array([[0, 0, -2.3, 5.0], [0, 0, -1.8, 6.0], [0, 0, -0.3, 7.0]])
    spin = records_from(cycle[np.arange(RECORD) % 3], rotations=1.0)
    assert classify_records(spin, UNIT, Status.OK, never).label == "rotating"
    assert classify_records(spin, UNIT, Status.DIVERGED, never).label == "n/a"


def paper_point(params, transient, record):
    backend = make_backend("emulated")
    run = backend.run_point(params, backend.initial_state(params, 0.0, 0.0, 0.1, 0.0), transient, record)
    return classify_run(backend, params, run)


def test_fig9_po_is_periodic():
    # Pendulum at fe/2: period 2 in forcing periods.
    assert paper_point(FIG9_PO, 100, 20).label == "periodic-2"


def test_fig9_co_is_chaotic_while_the_paper_recorded_it():
    # From theta = 0.1 rad the first 70 periods have a clearly positive exponent ...
    motion = paper_point(FIG9_CO, 0, 70)
    assert motion.label == "chaotic"
    assert motion.lyapunov > 3 * motion.lyapunov_err > 0
    # ... but in the noiseless model it is a long transient: after the paper's
    # 100 transient periods it is no longer chaotic and later settles (docs/hopf-and-motion.md).
    assert paper_point(FIG9_CO, 100, 20).label == "transient"


def test_sweep_rows_carry_one_motion_per_unit():
    config = SweepConfig(parameter="alpha", values=(5.0, 30.0, 40.0), model={"fe": 2.5}, mode="fresh")
    df = run_sweep(config)
    per_unit = df.groupby("point")["motion"].agg(["nunique", "first"])
    assert (per_unit["nunique"] == 1).all()
    assert list(per_unit["first"]) == ["semi-trivial", "periodic-2", "rotating"]


def test_bifurcation_plot_shades_motion_bands():
    import matplotlib.pyplot as plt

    from pendsweep.figures.plotting import draw_bifurcation
    from pendsweep.studies.sweep import sweep_metadata

    config = SweepConfig(
        parameter="alpha",
        values=(5.0, 30.0, 40.0),
        model={"fe": 2.5},
        mode="fresh",
        transient_periods=100,
        record_periods=20,
    )
    fig, ax = plt.subplots()
    draw_bifurcation(ax, [(run_sweep(config), sweep_metadata(config))])
    legends = [child for child in ax.get_children() if isinstance(child, matplotlib.legend.Legend)]
    motion_legend = next(lg for lg in legends if lg.get_title().get_text() == "motion")
    assert [t.get_text() for t in motion_legend.get_texts()] == ["semi-trivial", "periodic", "rotating"]
    plt.close(fig)


def test_batched_evidence_gives_the_labels_of_point_by_point_evidence():
    """The extension and Lyapunov twin integrated as lanes of one batched launch (the fast path)
    label points as re-simulating each one period at a time with the scalar kernel does."""
    from pendsweep import TABLE_IV
    from pendsweep.analysis.classify import classify_runs

    backend = make_backend("emulated")

    class PointByPoint:  # the same backend without its batched evidence
        batched = False  # the contract's declaration: no batched kernel, no evidence_many
        restartable = True  # it can start from any state (the contract)
        noisy = False  # its records are noise-free (the contract)

        def run_point(self, *args):
            return backend.run_point(*args)

        def run_points(self, params, states, transient, record):  # the contract's point-by-point fallback
            return [backend.run_point(q, x, transient, record) for q, x in zip(params, states)]

        def initial_state(self, *args):
            return backend.initial_state(*args)

    cases = [  # (alpha [N], fe [Hz], theta0 [rad], thetadot0 [rad/s])
        (12.0, 2.2, 0.1, 0.0),  # the paper's CO: a long transient
        (40.0, 2.5, 2.0, 3.0),  # rotating
        (16.5, 2.5, 0.1, 0.0),  # slowly converging just above the Hopf boundary
        (44.0, 2.5, 1.0, 8.0),  # chaotic
        (30.0, 2.5, 2.5, -2.0),  # periodic-2, decided by the record
    ]
    params = [TABLE_IV.replace(alpha=a, fe=f) for a, f, _, _ in cases]
    runs = [
        backend.run_point(q, backend.initial_state(q, 0.0, 0.0, th, thd), 100, 20)
        for q, (_, _, th, thd) in zip(params, cases)
    ]
    fast = classify_runs(backend, params, runs, evidence="full")
    slow = classify_runs(PointByPoint(), params, runs)  # a backend without the batched kernel gets full evidence
    assert [m.label for m in fast] == [m.label for m in slow]
    assert all(m.extension_periods == EXTEND_PERIODS for m in slow if m.lyapunov_pair)
    assert {m.label for m in fast} >= {"chaotic", "rotating", "transient", "periodic-2"}
    for f, s in zip(fast, slow):
        if f.label != "chaotic" and math.isfinite(s.lyapunov):
            # The batched kernel's last bits differ (sincos_poly, reciprocals) and the CO point's
            # chaotic transient amplifies them: the estimates agree far inside their own error.
            assert abs(f.lyapunov - s.lyapunov) < 0.01 * s.lyapunov_err


def fresh_dense_sweep_points(indices):
    """Points (in ascending alpha) of the dense fresh sweep (alpha 0-45 N in steps of 0.05 N, fe = 2.5 Hz, M = 10.9 kg,
    100 + 20 periods from theta = 0.1 rad) by index: chaotic ones depend on alpha's last bits."""
    from pendsweep.studies.sweep import value_range

    backend = make_backend("emulated")
    alphas = value_range(0.0, 45.0, 0.05)[list(indices)]
    config = SweepConfig(parameter="alpha", values=tuple(alphas), model={"fe": 2.5, "M": 10.9}, mode="fresh")
    params = [config.params_at(a) for a in config.values]
    states = np.array([backend.initial_state(q, *config.initial) for q in params])
    return backend, params, backend.run_points(params, states, 100, 20)


def test_staged_evidence_labels_chaotic_points_as_full_evidence_does():
    """Chaotic points of the dense fresh sweep: tumbling ones (Lyapunov pair alone) and swinging ones
    (an extension that never repeats, then the pair) keep their label with staged evidence."""
    from pendsweep.analysis.classify import classify_runs

    # 38.1, 41.6 and 44.9 N tumble in the record; 42.3, 42.6 and 43.7 N swing.
    backend, params, runs = fresh_dense_sweep_points([762, 832, 846, 852, 874, 898])
    full = classify_runs(backend, params, runs, evidence="full")
    staged = classify_runs(backend, params, runs, evidence="staged")
    assert [m.label for m in full] == ["chaotic"] * 6
    assert [m.label for m in staged] == [m.label for m in full]
    assert [m.lyapunov for m in staged] == [m.lyapunov for m in full]  # the same pair, bit for bit
    assert [m.extension_periods for m in staged] == [0, 0] + [EXTEND_PERIODS] * 3 + [0]
    assert all(m.lyapunov_pair for m in staged)


def test_staged_evidence_calls_transient_chaos_that_settles_transient():
    """The one label of the dense fresh sweep that staged evidence changes: at 43.05 N the
    record is a chaotic transient whose section repeats within the extension; full evidence
    says chaotic (the record's Lyapunov exponent), staged evidence stops at the repeat."""
    from pendsweep.analysis.classify import classify_runs

    backend, params, runs = fresh_dense_sweep_points([861])  # 43.05 N
    (full,) = classify_runs(backend, params, runs, evidence="full")
    (staged,) = classify_runs(backend, params, runs, evidence="staged")
    assert (full.label, staged.label) == ("chaotic", "transient")
    assert not staged.lyapunov_pair and 0 < staged.extension_periods <= 200


def test_evidence_mode_is_checked():
    from pendsweep.analysis.classify import classify_runs
    from pendsweep.errors import ConfigError

    with pytest.raises(ValueError, match="evidence"):
        classify_runs(make_backend("emulated"), [], [], evidence="some")
    with pytest.raises(ConfigError, match="evidence"):
        SweepConfig(parameter="alpha", values=(1.0,), evidence="some")


# -- noisy records: tolerances from the record's own measured noise -------------------------------------------
ENCODER_STEP = 0.0013  # rad, Table III


def noisy_records(states, jitter, seed, envelope=None):
    """Records of ``states`` (k, 4) with Gaussian section jitter [~rad] and an encoder-quantised theta."""
    rng = np.random.default_rng(seed)
    states = np.asarray(states, dtype=float) + rng.normal(0.0, jitter, size=np.shape(states))
    states[:, 2] = np.round(states[:, 2] / ENCODER_STEP) * ENCODER_STEP
    rec = records_from(states)
    if envelope is not None:
        rec[:, REC["theta_absmax"]] = envelope
    rec[:, REC["theta_absmax"]] = np.round(rec[:, REC["theta_absmax"]] / ENCODER_STEP) * ENCODER_STEP
    return rec


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_noisy_periodic_n_repeats_within_its_measured_noise(n):
    """A period-n cycle under 1e-3 of jitter and an encoder's steps: periodic-n on a noisy backend for every
    seed, with the jitter measured to within 40 %; the noise-free rule (1e-3) cannot see the repeat."""
    cycle = np.random.default_rng(n).uniform(-0.5, 0.5, size=(n, 4))
    for seed in range(10):
        rec = noisy_records(cycle[np.arange(RECORD) % n], 1e-3, seed)
        motion = classify_records(rec, UNIT, Status.OK, never, noisy=True)
        assert motion.label == f"periodic-{n}", (seed, motion)
        assert 0.6e-3 < motion.noise.jitter[0] < 1.4e-3  # y: a continuous channel, true jitter 1e-3
        assert motion.noise.applied_tolerance > PERIODIC_TOL
        assert section_period(rec[:, SECTION_COLUMNS], UNIT) == 0
        assert classify_records(rec, UNIT, Status.OK, None).label == "transient"  # the noise-free rule


def test_noisy_records_that_do_not_repeat_are_left_to_the_evidence():
    """Motions that are not periodic (small tori, a converging spiral, chaos, chaos in narrow bands, a decaying
    swing that the section hides) and a jitter larger than noise are not read as periodic; a period-4 orbit
    whose halves differ by 20 jitters stays period 4."""
    rng = np.random.default_rng(7)
    k = np.arange(RECORD)[:, None]
    golden = 2 * math.pi * (math.sqrt(5) - 1) / 2
    torus = np.hstack([np.full((RECORD, 2), 0.3), 0.3 + 0.05 * np.cos(golden * k), 0.05 * np.sin(golden * k)])
    spiral = np.hstack([np.full((RECORD, 2), 0.3), 0.2 * 0.9**k * np.cos(0.3 * k), 0.2 * 0.9**k * np.sin(0.3 * k)])
    henon_orbit = orbit(henon, np.array([0.0, 0.0, 0.1, 0.1]), 100 + RECORD)[100:]
    two = rng.uniform(-0.5, 0.5, size=(2, 4))[np.arange(RECORD) % 2]
    hidden = np.tile([0.3, 0.3, 0.2, 0.4], (RECORD, 1))  # the section stands still ...
    decaying = 0.6 - 0.002 * np.arange(RECORD)  # ... while the swing decays
    for name, rec in {
        "torus": noisy_records(torus, 1e-3, 1),
        "spiral": noisy_records(spiral, 1e-3, 2),
        "henon": noisy_records(henon_orbit, 1e-3, 3),
        "too loud": noisy_records(two, 3 * NOISE_MAX, 4),
        "decaying swing": noisy_records(hidden, 1e-3, 5, envelope=decaying),
    }.items():
        motion = classify_records(rec, UNIT, Status.OK, None, noisy=True)
        assert motion.label == "transient" and not motion.noise.repeats, (name, motion)
    # The independent checker's cases: motions 20 to 60 times the jitter that 20 sections could take for noise.
    small = np.tile([0.3, 0.2, 0.4, 0.1], (RECORD, 1))
    for rho in (0.3, 0.45, 0.618):
        torus = small.copy()
        torus[:, 2:] += 0.01 * np.column_stack([np.cos(2 * np.pi * rho * k[:, 0]), np.sin(2 * np.pi * rho * k[:, 0])])
        for seed in range(10):
            assert classify_records(noisy_records(torus, 5e-4, seed), UNIT, Status.OK, None, noisy=True).label == (
                "transient"
            ), (rho, seed)
    logistic = [0.3]
    for _ in range(100 + RECORD):
        logistic.append(3.9 * logistic[-1] * (1 - logistic[-1]))
    banded = np.array([[0.3, 0.2, 0.4, 0.1], [-0.3, -0.2, -0.4, -0.1]])[np.arange(RECORD) % 2]
    banded[:, 2] += 0.02 * (np.array(logistic[-RECORD:]) - 0.5)  # chaos in two bands 0.02 wide
    for seed in range(10):
        assert classify_records(noisy_records(banded, 5e-4, seed), UNIT, Status.OK, None, noisy=True).label == (
            "transient"
        )
    four = rng.uniform(-0.5, 0.5, size=(2, 4))[np.arange(RECORD) % 2]
    four[::4] += 0.02  # halves of the period-2 pattern 0.02 apart: a period-4 orbit
    for seed in range(5):
        assert classify_records(noisy_records(four, 1e-3, seed), UNIT, Status.OK, never, noisy=True).label == (
            "periodic-4"
        )


def test_noisy_substructured_sweep_reads_like_the_noise_free_loop():
    """The default rig (load-cell noise, encoder, LVDT) on the period-2 branch of Fig. 11(a1): periodic-2 as the
    same loop without noise, where the old 1e-3 rule found no repeat; rest stays rest and the irregular motion at
    42 N is not called periodic. The rows say what was measured."""
    exact = {name: 0.0 for name in ("force_noise", "encoder_resolution", "lvdt_resolution", "lvdt_noise")}
    values = (5.0, 24.0, 28.0, 32.0, 36.0, 42.0)
    frames = {}
    for name, options in (("noisy", {}), ("exact", exact)):
        config = SweepConfig(
            parameter="alpha", values=values, model={"fe": 2.5}, mode="fresh", transient_periods=150,
            backend="substructured", backend_options=options,
        )  # fmt: skip
        frames[name] = run_sweep(config).groupby("alpha").first()
    noisy, exact_rows = frames["noisy"], frames["exact"]
    assert make_backend("substructured").noisy and not make_backend("substructured", **exact).noisy
    assert list(exact_rows["motion"].iloc[:5]) == ["semi-trivial"] + ["periodic-2"] * 4
    assert list(noisy["motion"].iloc[:5]) == list(exact_rows["motion"].iloc[:5])
    assert not any(rows["motion"].iloc[5].startswith("periodic") for rows in (noisy, exact_rows))  # 42 N
    branch = noisy.loc[[24.0, 28.0, 32.0, 36.0]]
    assert ((branch["section_noise"] > 1e-4) & (branch["section_noise"] < NOISE_MAX)).all()
    assert (branch["periodic_tol"] > PERIODIC_TOL).all()
    assert "section_noise" not in exact_rows.columns
    backend = make_backend("substructured")
    q = FIG9_PO.replace(alpha=30.0, fe=2.5)
    run = backend.run_point(q, backend.initial_state(q, 0.0, 0.0, 0.1, 0.0), 150, 20)
    assert section_period(run.records[:, SECTION_COLUMNS], section_scales(run.records, q)) == 0  # 1e-3 fails


def test_transient_auto_settles_a_noisy_loop_within_its_noise():
    """``--transient auto`` on the noisy substructured loop settles as the classifier judges (noisy tolerance),
    instead of running every point to the cap; a point at rest shows no measured noise."""
    config = SweepConfig(parameter="alpha", values=(5.0, 30.0), model={"fe": 2.5}, mode="fresh", transient="auto",
                         max_transient_periods=400, backend="substructured")  # fmt: skip
    rows = run_sweep(config).groupby("alpha").first()
    assert rows.loc[30.0, "motion"] == "periodic-2" and rows.loc[30.0, "settled"]
    assert rows.loc[30.0, "transient_periods_used"] < 400
    assert rows.loc[5.0, "motion"] == "semi-trivial" and np.isnan(rows.loc[5.0, "section_noise"])
