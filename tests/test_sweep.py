"""Sweep planner: ranges, modes, directions, parallelism, crash-safe resume."""

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from pendsweep import ConfigError, ParameterError, ResultsError
from pendsweep.engine.results import read_results
from pendsweep.studies.sweep import SweepConfig, multistart_initials, run_sweep, value_range

SHORT = dict(transient_periods=5, record_periods=3)


def test_value_range_is_inclusive_and_exact():
    v = value_range(0, 45, 0.5)
    assert len(v) == 91 and v[0] == 0 and v[-1] == 45 and v[1] == 0.5
    assert np.array_equal(value_range(0, 1, points=5), [0, 0.25, 0.5, 0.75, 1])
    assert np.allclose(value_range(1, 0, -0.25), [1, 0.75, 0.5, 0.25, 0])
    with pytest.raises(ConfigError, match="wrong sign"):
        value_range(0, 45, -0.5)
    with pytest.raises(ConfigError, match="non-zero"):
        value_range(0, 1, 0)


def test_config_rejects_bad_values():
    with pytest.raises(ParameterError, match=r"M = -1.0 kg is outside the accepted range \(0, inf\)"):
        SweepConfig("M", (-1.0, 2.0))
    with pytest.raises(ParameterError, match="unknown parameter"):
        SweepConfig("alpha", (1.0,), model={"mass": 3})
    with pytest.raises(ConfigError, match="unknown parameter"):
        SweepConfig("bogus", (1.0,))
    with pytest.raises(ParameterError, match="fe"):
        SweepConfig("fe", (float("nan"),))
    with pytest.raises(ConfigError, match="mode"):
        SweepConfig("alpha", (1.0,), mode="sideways")
    # A copy checks what changes, the masses and dampings derived from M1/C1 included.
    from pendsweep.model.params import TABLE_IV

    with pytest.raises(ParameterError, match="M = inf kg"):
        TABLE_IV.replace(M1=1.7e308, M2=1.7e308)
    with pytest.raises(ParameterError, match="C = inf kg/s"):
        TABLE_IV.replace(C1=1.7e308, C2=1.7e308)
    with pytest.raises(ParameterError, match="K = -3.0"):
        TABLE_IV.replace(K=-3.0)
    moved = TABLE_IV.replace(M1=5.0, alpha=12)
    assert (moved.M, moved.alpha, moved.M2, type(moved.alpha)) == (5.0 + TABLE_IV.M2, 12.0, TABLE_IV.M2, float)
    assert moved == dataclasses.replace(TABLE_IV, M=5.0 + TABLE_IV.M2, alpha=12.0)


def test_long_form_schema_and_row_count():
    config = SweepConfig("alpha", (1.0, 2.0, 3.0), direction="both", **SHORT)
    df = run_sweep(config)
    assert len(df) == 2 * 3 * 3
    expected = [
        "alpha",
        "direction",
        "point",
        "start",
        "period",
        "theta_peak",
        "theta_absmax",
        "y_sec",
        "ydot_sec",
        "theta_sec",
        "thetadot_sec",
        "y_absmax",
        "rotations",
        "kicked",
        "status",
        "motion",
    ]
    assert list(df.columns) == expected
    down = df[df.direction == "down"]
    assert down.groupby("point").size().to_dict() == {0: 3, 1: 3, 2: 3}


def test_table_and_frame_results_agree_with_and_without_a_file(tmp_path):
    """``as_frame=False`` (what the CLI uses) gives the DataFrame's rows, in its order, as a pyarrow Table."""
    config = SweepConfig("alpha", (1.0, 18.0, 30.0), direction="both", **SHORT)
    frame = run_sweep(config)
    for output in (None, tmp_path / "t.parquet"):
        table = run_sweep(config, output, as_frame=False)
        assert table.column_names == list(frame.columns)
        pd.testing.assert_frame_equal(table.to_pandas(), frame)
    pd.testing.assert_frame_equal(read_results(tmp_path / "t.parquet")[0], frame)


def test_continue_carries_state_and_down_branch_starts_at_the_top(emulated):
    config = SweepConfig("alpha", (20.0, 25.0), direction="both", **SHORT)
    df = run_sweep(config)
    # The down branch's first point (alpha = 25) starts from the initial condition ...
    p25 = config.params_at(25.0)
    fresh = emulated.run_point(p25, emulated.initial_state(p25, 0, 0, 0.1, 0), 5, 3).records
    got = df[(df.direction == "down") & (df.point == 1)].sort_values("period")
    assert np.array_equal(got["theta_absmax"].to_numpy(), fresh[:, 1])
    # ... while the up branch reaches alpha = 25 with the state carried from alpha = 20.
    up = df[(df.direction == "up") & (df.point == 1)].sort_values("period")
    assert not np.array_equal(up["theta_absmax"].to_numpy(), fresh[:, 1])


def test_kick_only_when_at_rest():
    config = SweepConfig("alpha", (0.0, 0.0, 20.0, 20.0), **dict(transient_periods=100, record_periods=5))
    df = run_sweep(config).groupby("point")["kicked"].first()
    assert list(df) == [False, True, True, False]  # rest at 0 N -> kick; swinging at 20 N -> none


def test_rest_threshold_reaches_the_kick_and_the_motion_label():
    """One "at rest" rule: --rest-threshold decides the kick and the semi-trivial label alike."""
    swinging = SweepConfig("alpha", (20.0, 20.0), **SHORT)
    default = run_sweep(swinging).groupby("point")[["kicked", "motion"]].first()
    assert default["motion"].iloc[0] != "semi-trivial" and not default["kicked"].any()
    # Wrapped |theta| never exceeds pi, so below 4 rad every finished point is "at rest".
    lenient = run_sweep(SweepConfig("alpha", (20.0, 20.0), rest_threshold=4.0, **SHORT))
    labels = lenient.groupby("point")[["kicked", "motion"]].first()
    assert list(labels["motion"]) == ["semi-trivial", "semi-trivial"] and list(labels["kicked"]) == [False, True]


def test_diverged_point_is_recorded_and_branch_restarts(emulated):
    config = SweepConfig("alpha", (1.0, 2.0, 1e300), direction="down", **SHORT)
    df = run_sweep(config)
    status = df.groupby("point")["status"].first().to_dict()
    assert status == {0: "ok", 1: "ok", 2: "diverged"}
    assert df[df.point == 2]["theta_absmax"].isna().all()
    # After the divergence the branch restarts from the initial condition.
    p2 = config.params_at(2.0)
    fresh = emulated.run_point(p2, emulated.initial_state(p2, *config.initial), 5, 3).records
    assert np.array_equal(df[df.point == 1].sort_values("period")["theta_absmax"].to_numpy(), fresh[:, 1])


def test_parallel_equals_serial():
    config = SweepConfig("alpha", tuple(value_range(10, 20, 2.5)), mode="fresh", **SHORT)
    a = run_sweep(config, n_jobs=1)
    b = run_sweep(config, n_jobs=2)
    pd.testing.assert_frame_equal(a, b)
    both = SweepConfig("alpha", (18.0, 20.0), direction="both", **SHORT)
    pd.testing.assert_frame_equal(run_sweep(both, n_jobs=1), run_sweep(both, n_jobs=2))


def test_multistart_is_seeded_and_reproducible():
    config = SweepConfig("alpha", (39.0, 40.0), mode="multistart", starts=4, seed=7, **SHORT)
    a, b = run_sweep(config, n_jobs=2), run_sweep(config, n_jobs=1)
    pd.testing.assert_frame_equal(a, b)
    assert a.groupby("point")["start"].nunique().tolist() == [4, 4]
    ic7 = multistart_initials(config, 0)
    ic8 = multistart_initials(SweepConfig("alpha", (39.0, 40.0), mode="multistart", starts=4, seed=8), 0)
    assert np.array_equal(ic7[0], [0, 0, 0.1, 0]) and not np.array_equal(ic7[1:], ic8[1:])
    assert np.all(np.abs(ic7[:, 2]) <= np.pi)


def test_metadata_holds_resolved_config_and_regenerates(tmp_path):
    config = SweepConfig("fe", (2.4, 2.5), model={"alpha": 12.0}, seed=3, **SHORT)
    out = tmp_path / "fe.parquet"
    df = run_sweep(config, out)
    meta = json.loads(pq.read_schema(out).metadata[b"pendsweep"])
    assert meta["config"]["model"]["alpha"] == 12.0 and meta["config"]["model"]["m"] == 0.27
    assert meta["backend"] == "emulated" and meta["seed"] == 3 and "package_version" in meta and "created" in meta
    again = run_sweep(SweepConfig.from_dict(meta["config"]), tmp_path / "again.parquet")
    pd.testing.assert_frame_equal(df, again)


def test_rerun_of_finished_file_returns_it_and_other_config_is_refused(tmp_path):
    out = tmp_path / "a.parquet"
    config = SweepConfig("alpha", (1.0, 2.0), **SHORT)
    first = run_sweep(config, out)
    mtime = out.stat().st_mtime_ns
    pd.testing.assert_frame_equal(run_sweep(config, out), first)
    assert out.stat().st_mtime_ns == mtime
    with pytest.raises(ResultsError, match="different configuration"):
        run_sweep(SweepConfig("alpha", (1.0, 3.0), **SHORT), out)
    run_sweep(SweepConfig("alpha", (1.0, 3.0), **SHORT), out, overwrite=True)


def test_unwritable_output_is_a_clear_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ResultsError, match="cannot write results"):
        run_sweep(SweepConfig("alpha", (1.0,), **SHORT), blocker / "out.parquet")


def test_killed_sweep_resumes_without_loss_or_duplication(tmp_path):
    """Kill a real sweep process with SIGKILL mid-run, rerun, compare with an uninterrupted run."""
    out = tmp_path / "killed.parquet"
    args = [
        sys.executable,
        "-m",
        "pendsweep.cli",
        "alpha",
        "--from",
        "0",
        "--to",
        "45",
        "--step",
        "0.5",
        "--transient-periods",
        "60",
        "--record-periods",
        "10",
        "-j",
        "1",
        "-o",
        str(out),
        "--no-progress",
        "--checkpoint-seconds",
        "0",  # a part per point: the kill lands mid-run however fast the machine
    ]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    parts = out.with_name(out.name + ".parts")
    deadline = time.time() + 120
    while time.time() < deadline and len(list(parts.glob("part-*.parquet"))) < 2 and proc.poll() is None:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    n_parts = len(list(parts.glob("part-*.parquet")))
    assert n_parts >= 2 and not out.exists(), "the sweep should have been killed mid-run"
    done = subprocess.run(args, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    resumed, _ = read_results(out)
    assert not parts.exists()
    reference = run_sweep(SweepConfig("alpha", tuple(value_range(0, 45, 0.5)), transient_periods=60, record_periods=10))
    assert not resumed.duplicated(["direction", "point", "start", "period"]).any()
    pd.testing.assert_frame_equal(resumed, reference)


def test_result_files_get_normal_permissions(tmp_path):
    out = tmp_path / "perm.parquet"
    run_sweep(SweepConfig("alpha", (1.0,), **SHORT), out)
    umask = os.umask(0o022)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask


def test_adaptive_transient_reaches_what_a_long_fixed_transient_reaches():
    """--transient auto stops each point once it has settled; the labels are those of a
    1000-period fixed transient, reached with fewer periods, and the rows say how many."""
    # unforced (the oscillator decays to rest too); comes to rest; slow decay below Hopf; slow growth above; period-2
    values = (0.0, 6.0, 14.0, 16.5, 30.0)
    auto = run_sweep(SweepConfig("alpha", values, mode="fresh", transient="auto", max_transient_periods=1000))
    long = run_sweep(SweepConfig("alpha", values, mode="fresh", transient_periods=1000))
    short = run_sweep(SweepConfig("alpha", values, mode="fresh"))  # the paper's 100 periods
    first = auto.groupby("point").first()
    assert first["settled"].all()
    assert list(first["motion"]) == list(long.groupby("point").first()["motion"])
    assert (first["transient_periods_used"] < 1000).all()
    assert first["transient_periods_used"].iloc[-1] < 100  # the period-2 orbit settles before the paper's 100
    assert (short.groupby("point").first()["motion"] == "transient").any()  # what auto resolves


@pytest.mark.parametrize("name", ["fig11a", "fig11b"])
def test_staged_evidence_gives_the_labels_of_full_evidence_on_fig11(name):
    """The classifier's staged evidence (extensions that stop at a repeat, the Lyapunov pair only
    where still undecided) labels every point of the paper's Fig. 11 sweeps as the full evidence does."""
    from pendsweep.studies.sweepfile import load_sweep

    config = load_sweep(name).config
    staged = run_sweep(config)
    full = run_sweep(dataclasses.replace(config, evidence="full"))
    assert config.evidence == "staged"
    assert staged["motion"].tolist() == full["motion"].tolist()
    assert "transient" in set(staged["motion"])  # points the evidence had to decide
