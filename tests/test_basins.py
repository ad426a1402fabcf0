"""Settling detection, attractor identification and basins (issue 14).

The basin engine is checked on a system with known basins first: the damped
double-well Duffing oscillator x'' + delta x' - x + x^3 = 0, integrated here
by its own RK4 (independent of the package's kernels) and seen as a
stroboscopic map. Its two wells are mirror images under (x, v) -> (-x, -v),
so on a grid symmetric about 0 the two basins hold exactly the same number
of starts; energy E = v^2/2 - x^2/2 + x^4/4 only decreases, so every start
with E < 0 stays in the well of its sign of x; and an independent
integrator (scipy's DOP853) gives the same well for every start.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import solve_ivp

from pendsweep.analysis.attractors import MATCH_TOL, SETTLE_TOL, cycle_distance, settling
from pendsweep.analysis.sections import section_difference, section_period
from pendsweep.backends._batch import run_batch
from pendsweep.cli import main
from pendsweep.errors import ConfigError
from pendsweep.kernels import N_RECORD_COLUMNS
from pendsweep.model.params import ModelParams
from pendsweep.studies.basins import (
    BasinConfig,
    EmulatedMap,
    escape_rate,
    run_basins,
    scan_summary,
    settle_runs,
    summarize,
)

DELTA = 0.25  # Duffing damping
PERIOD = 2.0  # stroboscopic period [time units]
STEPS = 40  # RK4 steps per period


class DuffingMap:
    """Unforced damped double-well Duffing oscillator, RK4, as a stroboscopic map.

    The coordinate and velocity go in the theta columns of the record
    layout; the y columns stay zero (a one-degree-of-freedom system).
    """

    def advance(self, states, periods, ids):
        x, v = states[:, 0].copy(), states[:, 1].copy()
        h = PERIOD / STEPS
        rec = np.zeros((len(x), periods, N_RECORD_COLUMNS))

        def f(x, v):
            return v, -DELTA * v + x - x * x * x  # odd in (x, v): mirror starts stay exact mirrors

        for p in range(periods):
            peak = np.zeros_like(x)
            for _ in range(STEPS):
                k1x, k1v = f(x, v)
                k2x, k2v = f(x + 0.5 * h * k1x, v + 0.5 * h * k1v)
                k3x, k3v = f(x + 0.5 * h * k2x, v + 0.5 * h * k2v)
                k4x, k4v = f(x + h * k3x, v + h * k3v)
                x = x + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
                v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
                peak = np.where(np.abs(x) > np.abs(peak), x, peak)
            rec[:, p, 0], rec[:, p, 1] = peak, np.abs(peak)
            rec[:, p, 4], rec[:, p, 5] = x, v
        return rec, np.stack([x, v], axis=1), np.zeros(len(x), dtype=np.int64)

    def scales_for(self, ids, records):
        return np.ones((len(ids), 4))


def duffing_wells(starts: np.ndarray, max_periods: int = 300):
    runs = settle_runs(DuffingMap(), starts, max_periods)
    summary, labels, attractors = summarize(runs, max_periods)
    return runs, summary, labels, attractors


def energy(x, v):
    return 0.5 * v * v - 0.5 * x * x + 0.25 * x**4


def test_duffing_symmetric_grid_equal_basins_and_energy_wells():
    g = (np.arange(40) + 0.5) / 40 * 4 - 2  # cell centres on [-2, 2], symmetric about 0
    xx, vv = np.meshgrid(g, g, indexing="ij")
    starts = np.stack([xx.ravel(), vv.ravel()], axis=1)
    runs, summary, labels, attractors = duffing_wells(starts)
    assert runs.settled.all()
    # Two attractors, the wells x = +-1 (fixed points: period 1), each found once, mirror images.
    assert [a.motion for a in attractors] == ["periodic-1", "periodic-1"]
    wells = sorted(float(a.cycle[0, 2]) for a in attractors)
    assert wells == pytest.approx([-1.0, 1.0], abs=2 * SETTLE_TOL)
    assert summary["attractors"][0]["mirror"] == 1 and summary["attractors"][1]["mirror"] == 0
    # Symmetry: exactly equal basins on the symmetric grid, start by mirrored start.
    counts = [a["count"] for a in summary["attractors"]]
    assert counts[0] == counts[1] == starts.shape[0] // 2
    mirror = (39 - np.arange(40))[:, None] * 40 + (39 - np.arange(40))[None, :]
    assert (labels.reshape(40, 40) != labels[mirror]).all()
    # Energy below the saddle's (E < 0): trapped in the well of its own sign of x.
    well_x = np.array([a.cycle[0, 2] for a in attractors])[labels]
    trapped = energy(starts[:, 0], starts[:, 1]) < 0
    assert trapped.sum() > 100
    assert (np.sign(well_x[trapped]) == np.sign(starts[trapped, 0])).all()
    # The fast-rotating spiral repeats after 2 periods before it does after 1: it must not be called period-2.
    assert (runs.period == 1).all()


def test_duffing_basins_agree_with_independent_integrator():
    rng = np.random.default_rng(7)
    starts = np.stack([rng.uniform(-2, 2, 30), rng.uniform(-2, 2, 30)], axis=1)
    _, _, labels, attractors = duffing_wells(starts)
    well_x = np.array([a.cycle[0, 2] for a in attractors])[labels]

    def rhs(t, z):
        return [z[1], -DELTA * z[1] + z[0] - z[0] ** 3]

    for (x0, v0), w in zip(starts, well_x):
        end = solve_ivp(rhs, (0, 100), [x0, v0], method="DOP853", rtol=1e-9, atol=1e-11).y[0, -1]
        assert end == pytest.approx(w, abs=1e-3)


def test_binomial_standard_errors_match_the_spread_over_seeds():
    # 60 independent samples of 80 starts on an asymmetric window: the fractions' spread over the
    # samples must match the reported binomial standard error.
    groups, per = 60, 80
    rng = np.random.default_rng(11)
    starts = np.stack([rng.uniform(-0.6, 2.0, groups * per), rng.uniform(-1.5, 1.5, groups * per)], axis=1)
    runs = settle_runs(DuffingMap(), starts, 300)
    fractions, errors = [], []
    for g in range(groups):
        part = slice(g * per, (g + 1) * per)
        sub = type(runs)(**{k: v[part] for k, v in vars(runs).items()})
        summary, _, _ = summarize(sub, 300)
        right = next(a for a in summary["attractors"] if a["cycle"][0][2] > 0)
        fractions.append(right["fraction"])
        errors.append(right["stderr"])
    spread, reported = np.std(fractions, ddof=1), np.sqrt(np.mean(np.square(errors)))
    # The sample std of 60 values is known to about 1/sqrt(2*59) = 9 %: allow 3 of those.
    assert spread == pytest.approx(reported, rel=0.3)
    assert 0.5 < np.mean(fractions) < 0.95  # the window favours the right well


# -- the settling detector on constructed records ------------------------------------


def _records(sections: np.ndarray, rotations=None) -> np.ndarray:
    rec = np.zeros((sections.shape[0], N_RECORD_COLUMNS))
    rec[:, 2:6] = sections
    rec[:, 1] = 0.5
    rec[:, 6] = 1.0
    if rotations is not None:
        rec[:, 7] = rotations
    return rec


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8])
def test_settling_finds_the_classifiers_period(n):
    rng = np.random.default_rng(n)
    cycle = rng.uniform(-1, 1, (n, 4))
    sections = np.concatenate([rng.uniform(-1, 1, (17, 4)), np.tile(cycle, (60 // n + 1, 1))[:60]])
    found = settling(_records(sections), np.ones(4))
    assert found.settled[0] and found.period[0] == n
    assert found.period[0] == section_period(sections[17:], np.ones(4))
    assert found.onset[0] == 17  # the random stretch ends at row 16
    assert not settling(_records(sections[:40]), np.ones(4)).settled[0] or n == 1


def test_default_sampling_is_multistarts():
    from pendsweep.studies.sweep import SweepConfig, multistart_initials

    config = BasinConfig("alpha", (30.0, 40.0), {"fe": 2.5}, samples=50, seed=4)
    sweep = SweepConfig("alpha", (30.0, 40.0), {"fe": 2.5}, mode="multistart", starts=51, seed=4)
    for point in range(2):
        theta0, thetadot0 = config.initial_conditions(point)
        ms = multistart_initials(sweep, point)[1:]
        assert theta0 == pytest.approx(ms[:, 2], rel=1e-15, abs=1e-15)
        assert thetadot0 == pytest.approx(ms[:, 3], rel=1e-14, abs=1e-14)


def test_vectorised_scales_are_the_classifiers():
    from pendsweep.analysis.attractors import section_scales_many
    from pendsweep.analysis.sections import section_scales

    p = ModelParams().replace(alpha=30.0, fe=2.5)
    rec = run_batch([p, p.replace(alpha=10.0)], np.array([[0, 0, 0.3, 0], [0, 0, 0.1, 0]]), 0, 30).records
    many = section_scales_many(rec, p.omega_e, p.omega_p)
    for i in range(2):
        assert many[i] == pytest.approx(section_scales(rec[i], p), rel=1e-15)


def test_settling_rotation_number_and_rest():
    cycle = np.array([[0.0, 0.0, 1.0, 5.0], [0.0, 0.0, -2.0, 6.0], [0.0, 0.0, 0.5, 7.0]])
    found = settling(_records(np.tile(cycle, (10, 1)), np.tile([1, 1, 0], 10)), np.ones(4))
    assert found.period[0] == 3 and found.turns[0] == 2
    assert found.rotation_number[0] == pytest.approx(2 / 3)
    assert found.motion[0] == "rotating"
    # A quasi-periodic rotation: one turn every period, section never repeating.
    drift = np.stack(
        [
            np.zeros(120),
            np.zeros(120),
            np.angle(np.exp(1j * 0.37 * np.arange(120) ** 1.01)),
            5 + np.sin(np.arange(120)),
        ],
        axis=1,
    )
    found = settling(_records(drift, np.ones(120)), np.ones(4))
    assert found.settled[0] and found.period[0] == 0 and found.rotation_number[0] == 1
    assert found.motion[0] == "rotating"
    tumbling = np.tile([1, 1, 0, 1, -1], 24)  # reverses and skips turns: not steady
    assert not settling(_records(drift, tumbling), np.ones(4)).settled[0]
    rest = _records(np.zeros((30, 4)))
    rest[:, 1] = 1e-4
    assert settling(rest, np.ones(4)).motion[0] == "semi-trivial"


def test_slow_spiral_into_period_two_is_not_called_period_six():
    # Deviation from a period-2 orbit rotating by ~2 pi / 3 every 2 periods, shrinking 0.5 % per period:
    # it repeats after 6 periods to 1e-3 long before it repeats after 2.
    k = np.arange(60)
    orbit = np.where(k[:, None] % 2 == 0, [0.1, 0.2, 1.0, 2.0], [-0.1, -0.2, -1.0, -2.0])
    dev = 0.004 * 0.995**k * np.exp(1j * (2 * np.pi / 3 + 1e-4) * (k // 2))
    sections = orbit.copy()
    sections[:, 2] += dev.real
    sections[:, 3] += dev.imag
    found = settling(_records(sections), np.ones(4))
    assert not found.settled[0] and found.ambiguous[0]
    assert np.abs(section_difference(sections[6:], sections[:-6], np.ones(4)))[-24:].max() < SETTLE_TOL


def test_escape_rate_of_exponential_and_non_exponential_survival():
    rng = np.random.default_rng(3)
    times = (40 + rng.exponential(50.0, 4000)).astype(np.int64)
    fit = escape_rate(times, 2000)
    assert abs(fit["rate"] - 1 / 50) < 3 * fit["stderr"] + 1 / 50 * 0.02  # + rounding to whole periods
    assert escape_rate((100 + rng.normal(0, 5, 4000)).astype(np.int64), 2000) is None


# -- the pendulum ------------------------------------------------------------------


def test_settling_matches_single_long_trajectories():
    # A run alone in its batch is bitwise the same whether integrated in rounds or in one go,
    # so the engine's settling time must equal the one read off a long record.
    p = ModelParams().replace(alpha=30.0, fe=2.5)
    rng = np.random.default_rng(5)
    for _ in range(6):
        state = np.array([[0.0, 0.0, rng.uniform(-np.pi, np.pi), rng.uniform(-p.omega_p, p.omega_p)]])
        runs = settle_runs(EmulatedMap((p,)), state, 600)
        assert runs.settled[0]
        n, t = int(runs.period[0]), int(runs.settle_periods[0])
        long = run_batch([p], state, 0, t + 400).records[0]
        scales = np.array([long[:, 6].max(), p.omega_e * long[:, 6].max(), 1.0, p.omega_p])
        mismatch = np.abs(section_difference(long[n:, 2:6], long[:-n, 2:6], scales)).max(axis=1)
        assert (mismatch[t - 1 :] < SETTLE_TOL).all()  # settled from period t on, 400 periods past the stop
        assert mismatch[t - 2] >= SETTLE_TOL  # and not earlier
        assert section_period(long[-50:, 2:6], scales) == n  # the classifier agrees on the period
        tail = long[-n:, 2:6]
        assert cycle_distance(tail[None], runs.cycle[0, :n], scales)[0] < MATCH_TOL


def test_rounds_of_many_runs_equal_each_run_alone():
    # Runs leave the batch in different rounds and the kept runs' histories are compacted each round:
    # every outcome must be what the run gives integrated alone (bitwise: a run's records do not depend
    # on its neighbours in a batch).
    p = ModelParams().replace(alpha=40.0, fe=2.5)
    rng = np.random.default_rng(11)
    states = np.column_stack([np.zeros(48), np.zeros(48), rng.uniform(-np.pi, np.pi, 48), rng.uniform(-8, 8, 48)])
    together = settle_runs(EmulatedMap((p,)), states, 400)
    assert len(np.unique(together.periods_done)) >= 4  # they really left in different rounds
    for i in range(len(states)):
        alone = settle_runs(EmulatedMap((p,)), states[i : i + 1], 400)
        for field in ("status", "settled", "period", "turns", "settle_periods", "escape_periods", "periods_done"):
            assert getattr(alone, field)[0] == getattr(together, field)[i], (field, i)
        np.testing.assert_array_equal(alone.cycle[0], together.cycle[i])
        np.testing.assert_array_equal(alone.theta_absmax[0], together.theta_absmax[i])


def test_pendulum_at_40N_phases_and_senses_of_rotation():
    config = BasinConfig("alpha", (40.0,), {"fe": 2.5}, samples=240, seed=2, max_periods=1000)
    summary, rows = scan_summary(config, run_basins(config))
    table = summary["attractors"]
    p2 = [a for a in table if a["motion"] == "periodic-2"]
    assert len(p2) == 1  # both phases of the subharmonic swing: one attractor
    members = rows[rows.attractor == p2[0]["id"]]
    assert len(members) > 50
    rotating = [a for a in table if a["motion"] == "rotating"]
    assert rotating and all(a["mirror"] is not None for a in rotating)  # each sense has its mirror image
    for a in rotating:
        b = table[a["mirror"]]
        assert a["rotation_number"] == -b["rotation_number"]
        assert abs(a["fraction"] - b["fraction"]) < 3 * math.hypot(a["stderr"], b["stderr"]) + 1e-12
    assert sum(summary["fractions"].values()) == pytest.approx(1.0)


def test_both_phases_of_period_two_are_visited():
    p = ModelParams().replace(alpha=30.0, fe=2.5)
    rng = np.random.default_rng(1)
    n = 60
    states = np.zeros((n, 4))
    states[:, 2], states[:, 3] = rng.uniform(-np.pi, np.pi, n), rng.uniform(-p.omega_p, p.omega_p, n)
    runs = settle_runs(EmulatedMap((p,)), states, 600)
    _, labels, attractors = summarize(runs, 600)
    a = attractors[0]
    assert a.motion == "periodic-2" and (labels == 0).sum() > 40
    phase = [
        int(np.argmin(np.abs(section_difference(a.cycle, runs.cycle[i, 0], a.scales)).max(axis=1)))
        for i in np.flatnonzero(labels == 0)
    ]
    assert set(phase) == {0, 1}


def test_resume_after_interruption_gives_the_same_file(tmp_path):
    config = BasinConfig("alpha", (30.0,), {"fe": 2.5}, samples=64, max_periods=300)
    whole = run_basins(config, tmp_path / "a.parquet", chunk_starts=16)

    class Interrupted(Exception):
        pass

    class StopAfterTwo:
        def map_unordered(self, tasks, n_jobs=1):
            for task in tasks[:2]:
                yield from task()
            raise Interrupted

        def close(self):
            pass

    with pytest.raises(Interrupted):
        run_basins(config, tmp_path / "b.parquet", chunk_starts=16, executor=StopAfterTwo())
    assert not (tmp_path / "b.parquet").exists()
    resumed = run_basins(config, tmp_path / "b.parquet", chunk_starts=16)
    cols = [c for c in whole.columns if c not in ("cycle", "scales")]
    assert whole[cols].equals(resumed[cols])
    # Parts cut into other units (another version, or a GPU's bigger units) are refused, not half reused.
    with pytest.raises(Interrupted):
        run_basins(config, tmp_path / "c.parquet", chunk_starts=16, executor=StopAfterTwo())
    with pytest.raises(ConfigError, match="units of another size"):
        run_basins(config, tmp_path / "c.parquet", chunk_starts=32)


def test_cli_basins_json_and_bad_input(tmp_path):
    runner = CliRunner()
    out = tmp_path / "b.json"
    args = [
        "basins",
        "--alpha",
        "30",
        "--fe",
        "2.5",
        "--grid",
        "6x5",
        "--max-periods",
        "400",
        "-o",
        str(tmp_path / "b.parquet"),
        "--json",
        str(out),
        "--no-progress",
    ]
    result = runner.invoke(main, args)
    assert result.exit_code == 0, result.output
    summary = json.loads(out.read_text())
    for key in ("fractions", "stderr", "unsettled", "settling_periods", "escape_rate", "attractors"):
        assert key in summary
    assert set(summary["settling_periods"]) >= {"median", "q90"}
    assert summary["runs"] == 30
    scan = tmp_path / "scan.json"
    result = runner.invoke(
        main,
        [
            "basins",
            "alpha",
            "--from",
            "30",
            "--to",
            "31",
            "--step",
            "1",
            "--samples",
            "12",
            "--max-periods",
            "300",
            "-o",
            str(tmp_path / "s.parquet"),
            "--json",
            str(scan),
            "--plot",
            str(tmp_path / "s.png"),
            "--no-progress",
        ],
    )
    assert result.exit_code == 0, result.output
    summary = json.loads(scan.read_text())
    assert summary["values"] == [30.0, 31.0] and len(summary["unsettled_after_100"]) == 2
    for fractions in summary["classes"].values():
        assert len(fractions) == 2
    assert all(sum(f[i] for f in summary["classes"].values()) == pytest.approx(1.0) for i in range(2))
    assert (tmp_path / "s.png").exists()
    for bad, word in (
        (["--grid", "0x5"], "--grid"),
        (["--theta", "2:1"], "--theta"),
        (["--starts", "0"], "--starts = 0"),
        (["--samples", "0"], "--starts = 0"),  # the old name: the message names the option as spelled now
        (["--max-periods", "5"], "--max-periods = 5"),
    ):
        r = runner.invoke(main, ["basins", "--alpha", "30", *bad, "-o", str(tmp_path / "x.parquet")])
        assert r.exit_code == 2 and word in r.output, r.output
        assert "Traceback" not in r.output


def test_unsettled_after_100_is_not_claimed_from_shorter_runs(tmp_path):
    """Runs capped at 50 periods cannot say what is unsettled after 100: NaN, and the summary says so
    (before: the runs unsettled at 50 were reported as unsettled after 100)."""
    out, js = tmp_path / "b.parquet", tmp_path / "b.json"
    args = ["basins", "alpha", "--from", "30", "--to", "31", "--step", "1", "--samples", "8", "--no-progress"]
    short = CliRunner().invoke(main, [*args, "--max-periods", "50", "-o", str(out), "--json", str(js)])
    assert short.exit_code == 0, short.output
    assert "unsettled after 100 periods not known" in short.output
    assert all(math.isnan(u) for u in json.loads(js.read_text())["unsettled_after_100"])
    full = CliRunner().invoke(main, [*args, "--max-periods", "100", "-o", str(tmp_path / "c.parquet")])
    assert full.exit_code == 0 and "not known" not in full.output, full.output


def test_cli_map_with_boundaries(tmp_path):
    from pendsweep.studies.maps import MapConfig, hopf_boundaries

    runner = CliRunner()
    result = runner.invoke(
        main,
        [
            "map",
            "alpha",
            "fe",
            "--alpha",
            "5:35:3",
            "--fe",
            "2.4:2.6:2",
            "--max-periods",
            "100",
            "-o",
            str(tmp_path / "m.parquet"),
            "--plot",
            str(tmp_path / "m.png"),
            "--no-progress",
        ],
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "m.png").exists()
    r = runner.invoke(main, ["map", "alpha", "fe", "--alpha", "5:35", "--fe", "2.5", "-o", str(tmp_path / "x.parquet")])
    assert r.exit_code == 2 and "FROM:TO:N" in r.output
    # Boundary curves: Eq. (12) at 2.5 Hz is 16.456 N (docs/hopf-and-motion.md), Floquet 16.097 N.
    b = hopf_boundaries(MapConfig("alpha", (0.0, 45.0), "fe", (2.5, 2.5)))
    assert b["analytic"].iloc[0] == pytest.approx(16.456, abs=0.01)
    assert b["floquet"].iloc[0] == pytest.approx(16.097, abs=0.01)


def test_dask_executor_gives_the_local_rows():
    distributed = pytest.importorskip("distributed")
    from pendsweep.engine.executors import DaskExecutor

    config = BasinConfig("alpha", (30.0, 40.0), {"fe": 2.5}, samples=24, max_periods=300)
    local = run_basins(config, chunk_starts=8)
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40
    )
    try:
        with distributed.Client(cluster) as client:
            remote = run_basins(config, chunk_starts=8, executor=DaskExecutor(client))
    finally:
        cluster.close()
    cols = [c for c in local.columns if c not in ("cycle", "scales")]
    assert remote[cols].equals(local[cols])
