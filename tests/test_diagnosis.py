"""Diagnosis on independently generated records (issue 11).

Records come from :mod:`pendsweep.measured.diagnose.testbench`, which shares no
integration code with the replay kernels: another RK4 at 0.1 ms with the
friction sign per stage, Eqs. (1)-(2) solved by Cramer's rule, a substructuring
rig with a second-order servo behind a transport delay and an integrating load
cell, Table III encoder quantisation, LVDT and load-cell noise and drift. Seeds
come from the test range (B); the verdict thresholds were chosen on the
calibration range (A) only.
"""

import itertools
import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from pendsweep.cli import main
from pendsweep.measured.diagnose import EFFECTS, Replay, diagnose
from pendsweep.measured.diagnose.fit import Fit
from pendsweep.measured.diagnose.judge import block_test
from pendsweep.measured.diagnose.pipeline import diagnose_records
from pendsweep.measured.diagnose.populations import truth_value
from pendsweep.measured.diagnose.testbench import CALIBRATION_SEEDS, TEST_SEEDS, Case, generate
from pendsweep.measured.records import find_free_swing_data, read_record, write_record
from pendsweep.model.params import ENCODER_RESOLUTION

SEED = TEST_SEEDS[0] + 101
_real = find_free_swing_data()
needs_real = pytest.mark.skipif(_real is None, reason="shared/data/measured/free-swing-rotary-pendulum not present")


def run(case):
    """The diagnosis a user gets: substructured records part by part (issue 22), others by their replay."""
    d = diagnose_records([generate(case)])
    return d, d.to_json()


def assert_estimates(js, effects, rel=0.1):
    for cause, truth in effects.items():
        p = EFFECTS[cause].param
        tol = 0.002 if p == "theta_offset" else rel * abs(truth)
        assert abs(js["estimate"][p] - truth) < tol, (cause, js["estimate"][p], truth)


def test_seed_ranges_do_not_overlap():
    assert SEED in TEST_SEEDS and not set(TEST_SEEDS) & set(CALIBRATION_SEEDS)


def test_block_test_carries_information_on_zero_blocks():
    """Blocks where both models are exact (a resting, quantised pendulum) neither break nor decide the test."""

    def fit(blocks):
        return Fit((), {}, {}, 0.0, 0.0, [], np.array(blocks), [], 0.0)

    before = fit([0.0] * 8 + list(np.linspace(1.0, 2.0, 12)))
    better = fit([0.0] * 8 + list(np.linspace(0.01, 0.02, 12)))
    assert block_test(before, better) < 1e-3
    assert block_test(better, before) > 0.5
    assert block_test(before, before) == 1.0  # identical models: no evidence either way


def test_pendulum_at_rest_effect_found():
    """Forced below the Hopf boundary from rest: theta is exactly constant, y still carries the effect."""
    case = Case(
        "forced",
        {"oscillator_damping": truth_value("forced", "oscillator_damping", 0.5, 500.0)},
        rate=500.0,
        seed=SEED,
        theta_init=0.0,
    )
    d, js = run(case)
    assert np.ptp(d.replay.record.channel("theta")) == 0.0 and d.replay.constant == ("theta",)
    assert js["cause"] == "oscillator_damping" and js["validation"]["constant_channels"] == ["theta"]
    assert_estimates(js, case.effects)
    assert js["explained_share"] > 0.9 and not js["unexplained"]


@pytest.mark.parametrize(
    "kind, offset, rate",
    [
        ("forced", 0.015, 500.0),
        ("forced", 0.02, 2000.0),
        ("forced", 0.0011, 500.0),  # reads one encoder step: bounded, so certain (z >= sqrt 3, not 4)
        ("substructured", 0.09, 500.0),
        ("substructured", 0.07, 2000.0),
    ],
)
def test_encoder_zero_of_a_resting_pendulum_is_named(kind, offset, rate):
    """A pendulum resting through the record reads its encoder zero: the constant angle is a
    discrepancy of the nominal model (which rests at 0), named ``angle_offset`` within 2 mrad.

    Before, the constant channel was dropped: forced records gave ``none`` (explained), and
    substructured ones ``quadratic_drag`` with b3 some 10^5 x nominal, tied with the offset.
    """
    duration = (16.0 if kind == "forced" else 12.0) * (0.5 if rate > 1000 else 1.0)
    case = Case(kind, {"angle_offset": offset}, rate=rate, seed=SEED + 7, theta_init=0.0, duration=duration)
    d, js = run(case)
    assert js["cause"] == "angle_offset", js["cause"]
    assert_estimates(js, case.effects)
    assert js["explained_share"] > 0.9 and not js["unexplained"]
    if kind == "substructured":  # the encoder belongs to the specimen's replay (the physical part)
        d, js = d.physical, js["parts"]["physical"]
        assert js["cause"] == "angle_offset"
    assert d.replay.constant == ("theta",) and js["validation"]["constant_channels"] == ["theta"]
    # Known only to the reading's quantisation (half a step, uniform), which the stated one-sigma
    # uncertainty carries (before: 1e-9 to 3e-6 rad while the estimate was up to 0.6 mrad off).
    sigma = js["uncertainty"]["theta_offset"]
    assert sigma == pytest.approx(ENCODER_RESOLUTION / math.sqrt(12))  # exact: no calibration factor on it
    assert abs(js["estimate"]["theta_offset"] - offset) <= 2 * sigma
    # The level is the encoder zero: no other single cause comes close.
    runner_up = next(c for c in js["candidates"] if c["cause"] != "angle_offset" and "+" not in c["cause"])
    assert runner_up["error_after"] > 10 * js["error_after"]


def test_a_long_decay_with_a_wrong_length_is_named():
    """A free decay from 0.51 rad, 30 s, the arm 10 % long: the nominal model drifts cycles over
    the record, and its fitted initial state can be nonsense (a swing of hundredths of a radian).
    Started from there, the length fit stalled far off and the verdict was ``none`` (found by an
    independent check on its own 7 % record); candidates now also start from the data's state."""
    length = 1.10 * 0.1955
    case = Case("free_decay", {"pendulum_length": length}, rate=500.0, seed=SEED + 9, theta_init=0.51, duration=30.0)
    d, js = run(case)
    assert js["cause"] == "pendulum_length", js["cause"]
    assert js["estimate"]["l"] == pytest.approx(length, rel=0.01)
    assert not js["unexplained"]


def test_damping_cannot_absorb_a_resting_encoder_zero():
    """A resting pendulum's encoder zero with only the pendulum damping laws as candidates. The
    replay keeps the resting pendulum exactly at rest, so no damping law can move it: none is
    named and the level is flagged (before: quadratic drag absorbed it with b3 some 10^5 x
    nominal, and before that it was named)."""
    case = Case("substructured", {"angle_offset": 0.09}, rate=500.0, seed=SEED + 8, theta_init=0.0, duration=12.0)
    d = diagnose(Replay(generate(case)), ["quadratic_drag", "viscous_damping", "coulomb_friction"])
    js = d.to_json()
    assert js["cause"] == "none" and js["unexplained"] is True
    for c in js["candidates"]:
        assert c["error_after"] == pytest.approx(js["error_before"], rel=1e-6), c


def test_report_of_a_record_whose_pendulum_never_moves(tmp_path):
    """The report (figures and text) is written for the at-rest case too (theta is not compared)."""
    from pendsweep.measured.diagnose.report import write_report

    case = Case(
        "forced",
        {"oscillator_damping": truth_value("forced", "oscillator_damping", 0.5, 500.0)},
        rate=500.0,
        seed=SEED,
        theta_init=0.0,
    )
    d, _ = run(case)
    files = write_report(d, tmp_path, "at-rest record")
    assert (tmp_path / "signatures.png") in files and all(f.exists() for f in files)


@pytest.mark.parametrize(
    "kind, rate, at_rest",
    [
        ("free_decay", 500.0, False),
        ("forced", 2000.0, False),
        ("substructured", 500.0, False),
        ("forced", 500.0, True),
        ("substructured", 2000.0, True),
    ],
)
def test_clean_records_give_none_and_nothing_unexplained(kind, rate, at_rest):
    theta_init = 0.0 if at_rest else (1.0 if kind == "free_decay" else 0.3)
    duration = 6.0 if rate > 1000 else (12.0 if kind == "substructured" else 16.0)
    d, js = run(Case(kind, rate=rate, seed=SEED + 1, theta_init=theta_init, duration=duration))
    assert js["cause"] == "none" and js["estimate"] == {} and js["gain"] == 0.0
    assert js["unexplained"] is False and js["explained_share"] == 0.0


def test_decay_that_stops_early_is_coulomb_and_resting_tail_is_left_out():
    """Twelve times the nominal Coulomb friction stops a 0.4 rad swing within about 13 s of the
    20 s record: the comparison covers the moving part only, and the dry friction is named."""
    b1 = 12.0 * truth_value("free_decay", "coulomb_friction", 0.0, 500.0) / 2.0
    case = Case("free_decay", {"coulomb_friction": b1}, rate=500.0, seed=SEED + 2, theta_init=0.4, duration=20.0)
    d, js = run(case)
    theta = d.replay.meas["theta"]
    assert np.ptp(theta[-2000:]) == 0.0  # the pendulum rests for the last 4 s at least
    assert js["validation"]["compared_seconds"] < js["validation"]["record_seconds"] - 3.0
    assert js["cause"] == "coulomb_friction"
    assert_estimates(js, case.effects)


def test_single_effect_with_three_tones():
    case = Case(
        "forced",
        {"oscillator_stiffness": truth_value("forced", "oscillator_stiffness", 0.3, 500.0)},
        rate=500.0,
        duration=12.0,
        seed=SEED + 3,
        theta_init=0.3,
        tones=((5.0, 2.2), (2.0, 1.3), (1.0, 3.1)),
    )
    _, js = run(case)
    assert js["cause"] == "oscillator_stiffness"
    assert_estimates(js, case.effects)


def test_servo_rig_single_effect_gets_no_spurious_second_cause():
    """The replay's pure-delay actuator differs in form from the rig's servo; the verdict stays one cause."""
    case = Case(
        "substructured",
        {"platform_mass": truth_value("substructured", "platform_mass", 0.4, 500.0)},
        rate=500.0,
        seed=SEED + 4,
        theta_init=0.3,
        duration=12.0,
    )
    _, js = run(case)
    assert js["cause"] == "platform_mass"
    assert_estimates(js, case.effects)


@pytest.mark.parametrize("rate", [500.0, 2000.0])
def test_clean_substructured_replay_sits_at_the_noise_floor(rate):
    """The nominal replay of a clean servo-rig record leaves little more than sensor noise: each
    segment feeds back the recorded load-cell reading over its first tick, starts y* from the
    exact recorded command, and the record's first 50 ms serve as command history only (each of
    the three left a force spike that the loop carried through the segment: 3x the floor^2 at 2 kHz)."""
    rp = Replay(generate(Case("substructured", rate=rate, seed=SEED + 20, theta_init=0.3, duration=6.0)))
    assert rp.eval_idx[0] >= round(0.05 / rp.dt)
    assert rp.nrmse(rp.simulate({})) ** 2 < 2.0 * rp.noise_floor() ** 2


def test_replay_error_is_unimodal_in_the_delay():
    """A 2 kHz delay record: the replay error has one minimum in tau, near the truth, with no
    local minimum at every whole sample (where the local search used to stall)."""
    tau = truth_value("substructured", "actuator_delay", 0.5, 2000.0)
    rp = Replay(
        generate(
            Case("substructured", {"actuator_delay": tau}, rate=2000.0, seed=SEED + 21, theta_init=0.3, duration=6.0)
        )
    )
    taus = tau + rp.dt * np.arange(-3.0, 3.01, 0.2)
    err = np.array([rp.nrmse(rp.simulate({"tau": t})) for t in taus])
    k = int(np.argmin(err))
    assert abs(taus[k] - tau) < 0.5 * rp.dt
    assert np.all(np.diff(err[: k + 1]) < 0) and np.all(np.diff(err[k:]) > 0)


@pytest.mark.parametrize("cause", ["actuator_delay", "force_sensor_gain"])
def test_substructured_chain_effects_at_2khz(cause):
    """The benchmark's misses: at 2 kHz the delay was left `none` and the force-sensor gain named
    platform damping. Both are named now, with estimates within 3 %."""
    effects = {cause: truth_value("substructured", cause, 0.4, 2000.0)}
    case = Case("substructured", effects, rate=2000.0, seed=SEED + 22, theta_init=0.3, duration=6.0)
    _, js = run(case)
    assert js["cause"] == cause and js["unexplained"] is False
    assert_estimates(js, effects, rel=0.03)


def test_encoder_nonlinearity_on_a_servo_rig_is_flagged():
    """On substructured records the load cell's noise dominates the pooled floor; a structured
    residual in theta alone (encoder nonlinearity) is flagged by the channel's own noise."""
    case = Case(
        "substructured", {}, {"encoder_nonlinearity": 0.004}, rate=2000.0, seed=SEED + 23, theta_init=0.3, duration=6.0
    )
    _, js = run(case)
    assert js["cause"] == "none" and js["unexplained"] is True
    physical = js["parts"]["physical"]
    assert (
        physical["unexplained"] and physical["residual_to_noise"]["theta"] > 100 > physical["residual_to_noise"]["Fs"]
    )


@pytest.mark.parametrize(
    "kind, effects",
    [
        ("free_decay", {"pendulum_length": ("x", 0.5), "coulomb_friction": ("x", 0.3)}),
        ("forced", {"oscillator_damping": ("x", 0.6), "pendulum_length": ("x", 0.5)}),
    ],
)
def test_two_effects_named(kind, effects):
    truths = {c: truth_value(kind, c, u, 500.0) for c, (_, u) in effects.items()}
    case = Case(
        kind,
        truths,
        rate=500.0,
        seed=SEED + 5,
        theta_init=1.0 if kind == "free_decay" else 0.3,
        duration=20.0 if kind == "free_decay" else 16.0,
    )
    _, js = run(case)
    assert set(js["cause"].split("+")) == set(truths)
    assert_estimates(js, truths)


@pytest.mark.parametrize(
    "kind, extra",
    [
        ("free_decay", {"encoder_nonlinearity": 0.004}),
        ("forced", {"damping_drift": 1.5}),
        ("substructured", {"damping_drift": 1.5}),
    ],
)
def test_effect_outside_the_vocabulary_is_flagged_unexplained(kind, extra):
    case = Case(
        kind,
        {},
        extra,
        rate=500.0,
        seed=SEED + 6,
        theta_init=1.0 if kind == "free_decay" else 0.3,
        duration=12.0 if kind == "substructured" else 16.0,
    )
    _, js = run(case)
    assert js["unexplained"] is True
    if kind == "substructured":
        # The platform's damping drifts: the specimen's part names its mean change and is left unexplained;
        # the structure is in the load cell, the pendulum (which does not feel C2) stays at its noise.
        js = js["parts"]["physical"]
        assert js["unexplained"] is True and js["cause"] in ("none", "platform_damping")
        sig = js["residual_signature"]["record"]
        assert sig["Fs"]["lag1"] > 0.5 and js["residual_to_noise"]["theta"] < 3
        return
    sig = js["residual_signature"]["record"]
    assert all(sig[c]["lag1"] > 0.5 for c in sig if isinstance(sig[c], dict))  # structured, not sensor noise


def test_several_records_of_one_rig_one_answer(tmp_path):
    """Three free decays of one pendulum (different releases and encoder offsets): one cause set,
    validated by leave-one-record-out prediction, through the CLI."""
    b2 = truth_value("free_decay", "viscous_damping", 0.5, 500.0)
    paths = []
    for k, theta_init in enumerate((0.7, 1.1, 1.5)):
        rec = generate(
            Case(
                "free_decay",
                {"viscous_damping": b2},
                rate=250.0,
                seed=SEED + 10 + k,
                theta_init=theta_init,
                duration=10.0,
            )
        )
        paths += [str(write_record(rec, tmp_path / f"r{k}.csv")[0])]
    # The three damping laws and the length: the candidates a free decay can confuse.
    causes = [
        "--cause",
        "viscous_damping",
        "--cause",
        "coulomb_friction",
        "--cause",
        "quadratic_drag",
        "--cause",
        "pendulum_length",
    ]
    res = CliRunner().invoke(main, ["diagnose", *paths, *causes, "--json", str(tmp_path / "v.json")])
    assert res.exit_code == 0, res.output
    js = json.loads((tmp_path / "v.json").read_text())
    assert js["cause"] == "viscous_damping" and js["estimate"]["b2"] == pytest.approx(b2, rel=0.1)
    val = js["validation"]
    assert val["method"] == "leave-one-record-out" and len(val["cross_record_error"]) == 3
    assert max(val["cross_record_error"]) < 0.2 * min(val["cross_record_error_nominal"])


FREE_DECAY_CAUSES = ["viscous_damping", "coulomb_friction", "quadratic_drag", "pendulum_length"]


def test_joint_verdict_does_not_depend_on_the_order_of_the_records():
    """All six orders of three independent free decays of one rig (length and Coulomb friction
    hidden, three releases): the same verdict, estimates and candidate ranking."""
    b1 = truth_value("free_decay", "coulomb_friction", 0.5, 250.0)
    length = truth_value("free_decay", "pendulum_length", 0.5, 250.0)
    records = [
        generate(
            Case(
                "free_decay",
                {"coulomb_friction": b1, "pendulum_length": length},
                rate=250.0,
                seed=SEED + 20 + k,
                theta_init=theta_init,
                duration=8.0,
            )
        )
        for k, theta_init in enumerate((0.7, 1.1, 1.5))
    ]
    for k, rec in enumerate(records):
        rec.name = f"release{k}"
    verdicts = [
        diagnose([Replay(records[i]) for i in order], FREE_DECAY_CAUSES).to_json()
        for order in itertools.permutations(range(3))
    ]
    first = verdicts[0]
    assert set(first["cause"].split("+")) == {"coulomb_friction", "pendulum_length"}
    assert first["estimate"]["b1"] == pytest.approx(b1, rel=0.1)
    assert first["estimate"]["l"] == pytest.approx(length, rel=0.1)
    for js in verdicts[1:]:
        assert js["cause"] == first["cause"]
        assert js["validation"]["records"] == first["validation"]["records"]
        for k, v in first["estimate"].items():
            assert abs(js["estimate"][k] - v) <= first["fit_uncertainty"][k]
        assert [c["cause"] for c in js["candidates"]] == [c["cause"] for c in first["candidates"]]
    named = [c for c in first["candidates"] if c["status"] == "named"]
    assert [c["cause"] for c in named] == [first["cause"]]


def test_joint_fit_frees_each_records_encoder_zero():
    """Three free decays of one rig zeroed by hand (encoder zeros 0, +10 and -20 mrad, like real
    rigs): each record's zero is a nuisance of the joint fit, so the cause is named, its size
    recovered, the zeros found within 2 mrad, and nothing is left unexplained."""
    b2 = truth_value("free_decay", "viscous_damping", 0.5, 250.0)
    zeros = (0.0, 0.01, -0.02)
    records = []
    for k, (theta_init, zero) in enumerate(zip((0.7, 1.1, 1.5), zeros)):
        effects = {"viscous_damping": b2} | ({"angle_offset": zero} if zero else {})
        rec = generate(Case("free_decay", effects, rate=250.0, seed=SEED + 30 + k, theta_init=theta_init, duration=8.0))
        rec.name = f"zero{k}"
        records.append(rec)
    d = diagnose([Replay(r) for r in records], FREE_DECAY_CAUSES)
    js = d.to_json()
    assert js["cause"] == "viscous_damping" and js["estimate"]["b2"] == pytest.approx(b2, rel=0.1)
    assert js["unexplained"] is False
    for i, name in enumerate(js["validation"]["records"]):
        assert abs(js["nuisance"][f"theta_offset@{i}"] - zeros[int(name[-1])]) < 0.002


@needs_real
def test_real_free_swings_get_one_answer(tmp_path):
    """The three shared real records, in two orders: one answer for the rig, cross-record errors
    reported, and the better-fitting candidate that is not named says which test it failed.

    Candidates: the three damping laws and the length (the issue's three per-record verdicts
    differed in the damping law).
    """
    paths = [str(_real / f"free_swing_0{k}.txt") for k in (1, 2, 3)]
    causes = [a for c in FREE_DECAY_CAUSES for a in ("--cause", c)]
    res = CliRunner().invoke(
        main, ["diagnose", *paths, *causes, "--json", str(tmp_path / "v.json"), "--report", str(tmp_path / "rep")]
    )
    assert res.exit_code == 0, res.output
    js = json.loads((tmp_path / "v.json").read_text())
    assert (tmp_path / "rep" / "report.md").read_text().count("cross-record prediction NRMSE") == 3
    records = [read_record(p) for p in paths]
    for order in ((2, 1, 0),):
        other = diagnose([Replay(records[i]) for i in order], FREE_DECAY_CAUSES).to_json()
        assert other["cause"] == js["cause"]
        assert [c["cause"] for c in other["candidates"]] == [c["cause"] for c in js["candidates"]]
        assert other["candidates"][0]["estimate"] == pytest.approx(js["candidates"][0]["estimate"], rel=1e-9)
    best = js["candidates"][0]
    assert "pendulum_length" in best["cause"].split("+")
    # The arm's equivalent length from fit-damping is 0.0811-0.0818 m (docs/measured-data.md);
    # the time-series fit here agrees within two of its own standard errors (before calibration).
    assert abs(best["estimate"]["l"] - 0.0815) < 2 * best["fit_uncertainty"]["l"] + 0.0005
    nominal = js["validation"]["cross_record_error_nominal"]
    assert all(a < 0.5 * b for a, b in zip(best["cross_record_error"], nominal))
    # Quadratic drag alone absorbs what it can with b3 thousands of times its nominal: reported,
    # and rejected as physically implausible (not named, not started from in the second round).
    drag = next(c for c in js["candidates"] if c["cause"] == "quadratic_drag")
    assert drag["estimate"]["b3"] > 1000 * 9.17e-7
    assert drag["status"] == "rejected" and "implausible" in drag["reasons"][0]
    if best["cause"] != js["cause"]:
        # A better-fitting candidate that was not named says why.
        assert best["status"] in ("rejected", "not judged") and best["reasons"]
    else:
        assert js["explained_share"] > 0.5


@pytest.mark.parametrize("kind", ["free_decay", "substructured"])
def test_the_work_estimate_bounds_the_replays_a_diagnosis_runs(kind, monkeypatch):
    """diagnosis_work is an upper estimate of the replays, not a vacuous one (within 20 times)."""
    from pendsweep.measured.diagnose import replay as replay_module
    from pendsweep.measured.diagnose.fit import diagnosis_work

    case = Case(kind, seed=SEED + 7, theta_init=1.0 if kind == "free_decay" else 0.3, duration=8.0)
    rp = Replay(generate(case))
    steps = []
    simulate = replay_module.Replay.simulate

    def counted(self, values, stop=None):
        steps.append((self.n if stop is None else stop) * self.substeps)
        return simulate(self, values, stop)

    monkeypatch.setattr(replay_module.Replay, "simulate", counted)
    work = diagnosis_work([rp])
    diagnose(rp)
    assert work.total / 20 < sum(steps) <= work.total, (sum(steps), work.describe())


def test_diagnose_refuses_work_beyond_max_work_and_runs_with_yes(tmp_path):
    record = tmp_path / "rec.parquet"
    write_record(generate(Case("free_decay", seed=SEED + 8, theta_init=1.0, duration=4.0)), record)
    refused = CliRunner().invoke(main, ["diagnose", str(record), "--max-work", "1e5"])
    assert refused.exit_code == 2 and "this diagnosis needs about" in refused.output
    assert "replays" in refused.output and "pass --max-work" in refused.output
    accepted = CliRunner().invoke(main, ["diagnose", str(record), "--max-work", "1e5", "--yes"])
    assert accepted.exit_code == 0, accepted.output
    assert json.loads(accepted.output)["cause"] == "none"


def test_the_closed_loop_replay_samples_the_load_cell_at_the_tick_where_the_record_declares_it():
    """A loop whose load cell reads Eq. (4) at the tick (the replay's own kernel with ``point``, noise
    added): declared ``daq.load_cell = "point"`` the closed-loop replay sits at the noise floor; read
    as the default tick mean it does not."""
    import pandas as pd

    from pendsweep.kernels import substructured_replay
    from pendsweep.measured.records import Record
    from pendsweep.model.params import FIG9_PO

    p, dt, tau = FIG9_PO, 0.002, 0.004
    n = int(round(6.0 / dt)) + 1
    t = np.arange(n) * dt
    f = p.alpha * np.sin(2 * np.pi * p.fe * t)
    fh = p.alpha * np.sin(2 * np.pi * p.fe * (t[:-1] + dt / 2))
    out, cmd, cmdd = np.empty((n, 4)), np.zeros(n), np.zeros(n)
    state = np.array([0.0, 0.0, 0.3, 0.0])
    args = (p.M1, p.C1, p.M2, p.C2, f, fh, 1.0, 1.0, tau, dt, 2, cmd, cmdd, 0, out, math.nan, True)
    substructured_replay(state, p.kernel_array(), *args)
    rng = np.random.default_rng(SEED)
    data = pd.DataFrame({"t": t, "theta": out[:, 1] + rng.normal(0, 1e-4, n), "y": out[:, 0] + rng.normal(0, 2e-5, n),
                         "Fe": f, "y_cmd": out[:, 3], "Fs": out[:, 2] + rng.normal(0, 0.01, n)})  # fmt: skip
    ratios = {}
    for daq in ({"load_cell": "point"}, {}):
        rp = Replay(Record(data, "substructured", p, tau, {"alpha": p.alpha, "fe": p.fe}, daq=daq))
        ratios[bool(daq)] = rp.nrmse(rp.simulate({})) ** 2 / rp.noise_floor() ** 2
    assert ratios[True] < 2.0 < ratios[False], ratios
