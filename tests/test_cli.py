"""CLI: real sweeps end to end, and every bad input gives exit 2 with a clear message."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from pendsweep.cli import main
from pendsweep.engine.results import read_results

FAST = ["--transient-periods", "3", "--record-periods", "2", "--no-progress"]


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_alpha_sweep_writes_results_and_plot(tmp_path):
    out, png = tmp_path / "a.parquet", tmp_path / "a.png"
    r = invoke("alpha", "--from", 0, "--to", 2, "--step", 1, "--fe", 2.2, *FAST, "-o", out, "--plot", png)
    assert r.exit_code == 0, r.output
    df, meta = read_results(out)
    assert sorted(df["alpha"].unique()) == [0.0, 1.0, 2.0] and meta["config"]["model"]["fe"] == 2.2
    assert png.stat().st_size > 10_000
    r = invoke("plot", out, "-o", tmp_path / "b.pdf", "--observable", "theta_absmax")
    assert r.exit_code == 0, r.output


def test_mass_and_fe_and_generic_sweeps(tmp_path):
    for args in (
        ["mass", "--from", 5, "--to", 6, "--step", 1],
        ["fe", "--from", 2.4, "--to", 2.5, "--points", 2],
        ["sweep", "K", "--from", 1800, "--to", 1900, "--step", 100, "--set", "b1=0"],
    ):
        r = invoke(*args, *FAST, "-o", tmp_path / f"{args[0]}.parquet")
        assert r.exit_code == 0, r.output


def test_run_toml_and_regenerate_from_parquet(tmp_path):
    sweep = tmp_path / "s.toml"
    out = tmp_path / "s.parquet"
    sweep.write_text(
        f'parameter = "alpha"\nfrom = 1.0\nto = 2.0\nstep = 1.0\ntransient_periods = 3\n'
        f'record_periods = 2\noutput = "{out}"\n[model]\nfe = 2.2\n[backend]\nname = "emulated"\nsignum = "stage"\n'
    )
    assert invoke("run", sweep, "--no-progress").exit_code == 0
    again = tmp_path / "again.parquet"
    r = invoke("run", out, "-o", again, "--no-progress")
    assert r.exit_code == 0, r.output
    a, meta = read_results(out)
    b, _ = read_results(again)
    assert a.equals(b) and meta["config"]["backend_options"]["signum"] == "stage"


def test_shipped_sweep_definitions_load():
    from pendsweep.studies.sweepfile import builtin_sweeps, load_sweep

    assert set(builtin_sweeps()) >= {"fig11a", "fig11b"}
    a = load_sweep("fig11a")  # by name, as `pendsweep run fig11a`
    assert a.config.parameter == "alpha" and len(a.config.values) == 91 and a.config.model["fe"] == 2.5
    b = load_sweep(builtin_sweeps()["fig11b"])  # by path
    assert b.config.parameter == "M" and b.config.model["alpha"] == 17.0 and b.config.values[-1] == pytest.approx(13.0)


@pytest.mark.parametrize(
    "args, message",
    [
        (["mass", "--from", "-1", "--to", "5"], "M = -1.0 kg is outside the accepted range (0, inf)"),
        (["alpha", "--from", "0", "--to", "10", "--step", "-1"], "wrong sign"),
        (["alpha", "--from", "0", "--to", "10", "--step", "0"], "non-zero"),
        (["alpha", "--from", "0", "--to", "10", "--fe", "nan"], "not finite"),
        (["alpha", "--from", "0", "--to", "inf"], "not finite"),
        (["alpha", "--from", "0", "--to", "1", "--fe", "0"], "fe = 0.0 Hz is outside the accepted range (0, inf)"),
        (["alpha", "--from", "0", "--to", "1", "--K", "-5"], "K = -5.0 N/m"),
        (["alpha", "--from", "0", "--to", "1", "--set", "l=0"], "l = 0.0 m"),
        (["alpha", "--from", "0", "--to", "1", "--set", "length=2"], "unknown parameter 'length'"),
        (
            ["alpha", "--from", "0", "--to", "1", "--dt", "-0.001"],
            "'-0.001' s is outside the accepted range [1e-06, 0.01] s",
        ),
        (["alpha", "--from", "0", "--to", "1", "-B", "wobble=1"], "unknown option(s) wobble"),
        (["sweep", "stiffness", "--from", "0", "--to", "1", "--step", "1"], "unknown parameter 'stiffness'"),
        (["fe", "--from", "2", "--to", "3", "--mode", "sideways"], "Invalid value for '--mode'"),
    ],
)
def test_bad_input_exits_2_with_message(args, message):
    r = invoke(*args, "--no-progress")
    assert r.exit_code == 2, r.output
    assert message in r.output
    assert "Traceback" not in r.output


def test_unwritable_results_path_exits_2(tmp_path):
    blocker = tmp_path / "f"
    blocker.write_text("")
    r = invoke("alpha", "--from", 0, "--to", 1, *FAST, "-o", blocker / "x.parquet")
    assert r.exit_code == 2 and "cannot write -o/--output" in r.output


def test_toml_with_unknown_key_exits_2(tmp_path):
    sweep = tmp_path / "bad.toml"
    sweep.write_text('parameter = "alpha"\nfrom = 0\nto = 1\nstep = 1\ntransient = 5\n')
    r = invoke("run", sweep)
    assert r.exit_code == 2 and "unknown key(s) transient" in r.output
    r = invoke("run", tmp_path / "missing.toml")
    assert r.exit_code == 2 and "no sweep file" in r.output


def test_params_lists_units():
    r = invoke("params")
    assert r.exit_code == 0 and "alpha" in r.output and "N/m" in r.output


def test_figures_quick_smoke(tmp_path):
    r = invoke("figures", "fig8", "fig9", "fig11a", "--quick", "-o", tmp_path)
    assert r.exit_code == 0, r.output
    assert {p.name for p in tmp_path.glob("*.png")} == {"fig8.png", "fig9.png", "fig11a-quick.png"}
    assert invoke("figures", "fig99").exit_code == 2


def test_run_by_name_list_and_wrong_kind(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = invoke("run", "--list")
    assert r.exit_code == 0 and "fig11a" in r.output and "fig11b" in r.output
    r = invoke("run", "fig99")
    assert r.exit_code == 2 and "no built-in sweep" in r.output and "fig11a" in r.output
    hopf = tmp_path / "h.parquet"
    assert invoke("hopf", "--what", "1.1", "--method", "analytic", "-o", hopf, "--no-progress").exit_code == 0
    for args in (["run", hopf, "-o", tmp_path / "x.parquet"], ["plot", hopf]):
        r = invoke(*args)
        assert r.exit_code == 2 and "is a Hopf scan" in r.output and "Traceback" not in r.output


def test_default_output_replaced_for_another_configuration_and_resumed_for_the_same(tmp_path, monkeypatch):
    """A second, different query into the default path replaces the first with a note; the same one resumes."""
    from pendsweep.engine.results import read_metadata

    monkeypatch.chdir(tmp_path)
    default = tmp_path / "results" / "hopf.parquet"
    r = invoke("hopf", "--what", "1.1", "--method", "analytic", "--no-progress")
    assert r.exit_code == 0, r.output
    first = read_metadata(default)
    r = invoke("hopf", "--what", "1.0,1.05", "--method", "analytic", "--no-progress")
    assert r.exit_code == 0 and "held results of another configuration" in r.output
    second = read_metadata(default)
    assert second["config"]["omega_hat"] == [1.0, 1.05] and second["config_hash"] != first["config_hash"]
    r = invoke("hopf", "--what", "1.0,1.05", "--method", "analytic", "--no-progress")
    assert r.exit_code == 0 and "another configuration" not in r.output
    assert read_metadata(default)["created"] == second["created"]  # reused, not recomputed
    # an explicit -o is never replaced silently
    r = invoke("hopf", "--what", "1.2", "--method", "analytic", "--no-progress", "-o", default)
    assert r.exit_code == 2 and "different configuration" in r.output


def test_importing_pendsweep_leaves_the_matplotlib_backend_alone():
    code = "import pendsweep.cli, pendsweep.figures.plotting, pendsweep.figures, matplotlib; print(matplotlib.get_backend())"
    env = {**os.environ, "MPLBACKEND": "svg"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "svg"


def test_installed_wheel_runs_from_an_empty_folder(tmp_path):
    """The built wheel, installed away from the source tree, works from an empty folder.

    Dependencies come from the running interpreter; the package itself only
    from the wheel (asserted), so built-in sweeps, figures, default outputs and
    the matplotlib backend cannot lean on the checkout. The commands here need
    no kernel compilation (a fresh install compiles every numba kernel anew,
    minutes on a busy 2-core machine); `make wheel-check` runs the full
    `pendsweep run fig11a`, `figures fig8` and Hopf queries in a fresh venv.
    """
    root = Path(__file__).resolve().parents[1]
    dist, site, work = tmp_path / "dist", tmp_path / "site", tmp_path / "empty"
    work.mkdir()
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    built = subprocess.run(
        [*pip, "wheel", "--no-deps", str(root), "-w", str(dist)], capture_output=True, text=True, timeout=300
    )
    assert built.returncode == 0, built.stderr[-2000:]
    (wheel,) = dist.glob("pendsweep-*.whl")
    installed = subprocess.run(
        [*pip, "install", "--no-deps", "--target", str(site), str(wheel)], capture_output=True, text=True, timeout=300
    )
    assert installed.returncode == 0, installed.stderr[-2000:]
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PENDSWEEP_DATA", "MPLBACKEND")} | {
        "PYTHONPATH": str(site)
    }

    def python(*args, extra_env=None):
        out = subprocess.run(
            [sys.executable, *args], cwd=work, env=env | (extra_env or {}), capture_output=True, text=True, timeout=600
        )
        assert out.returncode == 0, out.stdout + out.stderr
        return out.stdout + out.stderr

    def pendsweep(*args):
        return python("-m", "pendsweep.cli", *args)

    assert Path(python("-c", "import pendsweep; print(pendsweep.__file__)").strip()).is_relative_to(site)
    assert "fig11a" in pendsweep("run", "--list")
    loaded = python(
        "-c",
        "from pendsweep.studies.sweepfile import load_sweep; s = load_sweep('fig11a'); print(s.config.parameter, len(s.config.values), s.output)",
    )
    assert loaded.split() == ["alpha", "91", "results/fig11a.parquet"]
    assert "fig5_margin.png" in pendsweep("figures", "fig5_margin")
    pendsweep("hopf", "--what", "1.1087", "--method", "analytic", "--no-progress")
    assert "another configuration" in pendsweep("hopf", "--what", "1.0,1.05", "--method", "analytic", "--no-progress")
    backend = "import pendsweep.figures.plotting, pendsweep.figures, matplotlib; print(matplotlib.get_backend())"
    assert python("-c", backend, extra_env={"MPLBACKEND": "svg"}).strip() == "svg"
    assert {p.name for p in (work / "results").rglob("*.p*")} == {"fig5_margin.png", "hopf.parquet"}


def test_click_usage_errors_are_one_line_too():
    """Errors click raises itself (unknown option or command, a value outside an IntRange) exit 2 in one line."""
    for args in (["alpha", "--bogus"], ["--bogus"], ["nosuchcmd"], ["alpha", "--seed", -1], ["alpha", "--step", "nan"]):
        r = invoke(*args)
        assert r.exit_code == 2 and r.output.count("\n") == 1 and r.output.startswith("Error: "), (args, r.output)
    r = invoke()  # no command: the group's help, as before
    assert "Commands:" in r.output


def test_corrupt_results_file_is_a_runtime_failure(tmp_path, monkeypatch):
    """Bad input exits 2; a results file that exists but cannot be read back exits 1 (one line, no traceback)."""
    monkeypatch.chdir(tmp_path)
    corrupt = tmp_path / "c.parquet"
    corrupt.write_bytes(b"PAR1 not really")
    for args in (
        ["alpha", "--from", 0, "--to", 1, *FAST, "-o", corrupt],
        ["hopf", "--what", "1.1", "--method", "analytic", "-o", corrupt],
    ):
        r = invoke(*args)
        assert r.exit_code == 1, r.output
        assert "c.parquet" in r.output and "cannot be read back" in r.output and r.output.count("\n") == 1
    # at the default path the unreadable file is replaced with a note, and --overwrite replaces it anywhere
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "hopf.parquet").write_bytes(b"garbage")
    r = invoke("hopf", "--what", "1.1", "--method", "analytic", "--no-progress")
    assert r.exit_code == 0 and "note: results/hopf.parquet held results of another configuration" in r.output
    r = invoke("hopf", "--what", "1.1", "--method", "analytic", "--no-progress", "-o", corrupt, "--overwrite")
    assert r.exit_code == 0, r.output


def test_help_imports_no_numerical_stack():
    """`pendsweep --help` (and building every command) loads no numpy, pandas, scipy, numba, matplotlib or joblib.

    Start-up time itself is measured, not asserted (see the report in the README);
    this checks the cause: the heavy modules stay unimported until a command runs.
    """
    heavy = ("numpy", "pandas", "pyarrow", "scipy", "numba", "matplotlib", "joblib")
    code = (
        "import sys; from click.testing import CliRunner; from pendsweep.cli import main; "
        "r = CliRunner().invoke(main, ['--help']); assert r.exit_code == 0, r.output; "
        f"print(sorted(m for m in {heavy!r} if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_measured_data_locator(tmp_path, monkeypatch):
    """$PENDSWEEP_DATA, else shared/data above the current folder; None (and a note from `figures`) when absent."""
    from pendsweep.measured.records import DATA_ENV, find_free_swing_data

    records = tmp_path / "shared" / "data" / "measured" / "free-swing-rotary-pendulum"
    records.mkdir(parents=True)
    monkeypatch.setenv(DATA_ENV, str(tmp_path / "shared" / "data"))
    assert find_free_swing_data() == records
    monkeypatch.setenv(DATA_ENV, str(tmp_path / "nowhere"))
    assert find_free_swing_data() is None
    r = invoke("figures", "free_swing_damping", "-o", tmp_path / "figs")
    assert r.exit_code == 0 and "skipped, its measured data were not found (set PENDSWEEP_DATA" in r.output
    monkeypatch.delenv(DATA_ENV)
    monkeypatch.chdir(records.parent)  # a folder below shared/data/measured: found by walking up
    assert find_free_swing_data() == records


# -- one spelling per option across commands (issue 24) -------------------------------------------------
#: The spellings of options that write a file, one per kind (README, "Using it").
FILE_WRITING = {
    "--output": "the file or folder a command writes",
    "--plot": "an extra figure",
    "--json": "a JSON summary beside what the command prints or writes",
    "--report": "a report folder",
    "--params-out": "a fitted model, as a ModelParams JSON",
}
#: Path-valued options that read a file.
FILE_READING = {"--model", "--start", "--overlay"}
#: Spellings of a quantity that has one canonical spelling; visible on any command, they are errors.
SYNONYMS = {
    "--out": "--output", "--outdir": "--output", "--output-dir": "--output", "--outfile": "--output",
    "--json-out": "--json", "--figure": "--plot", "--png": "--plot", "--param": "--set", "--params": "--set",
    "--theta-init": "--theta0", "--thetadot-init": "--thetadot0", "--n-jobs": "--jobs", "--threads": "--jobs",
    "--rng-seed": "--seed", "--model-file": "--model", "--backend-opt": "--backend-option",
}  # fmt: skip


def _visible_options():
    import click

    for name, command in sorted(main.commands.items()):
        for param in command.params:
            if isinstance(param, click.Option) and not param.hidden:
                yield name, param


def test_every_file_writing_option_has_its_one_spelling():
    import click

    wrong = []
    for name, param in _visible_options():
        is_path = isinstance(param.type, click.Path) or "Path" in type(param.type).__name__
        long = [o for o in param.opts if o.startswith("--")]
        if is_path and not set(long) & (set(FILE_WRITING) | FILE_READING):
            wrong.append(f"{name} {'/'.join(param.opts)}")
        if "--output" in long and "-o" not in param.opts:
            wrong.append(f"{name} --output without -o")
        # an option with a default file is written on every run: it is the command's output
        if is_path and "(default" in (param.help or "") and "--output" not in long:
            wrong.append(f"{name} {'/'.join(param.opts)} writes by default but is not -o/--output")
    assert not wrong, f"file options outside {sorted(FILE_WRITING)}: {wrong}"


def test_no_quantity_is_spelled_two_ways():
    found = [
        f"{name} {opt} (use {SYNONYMS[opt]})" for name, p in _visible_options() for opt in p.opts if opt in SYNONYMS
    ]
    assert not found, found


def test_every_command_writing_one_file_takes_it_as_minus_o():
    """A positional output file (synth OUT, trace OUTPUT) is the older spelling kept beside -o/--output."""
    import click

    positional_only = [
        name
        for name, command in sorted(main.commands.items())
        for param in command.params
        if isinstance(param, click.Argument) and param.name in ("out", "output") and param.required
    ]
    assert not positional_only, positional_only


@pytest.mark.parametrize(
    "command, extra",
    [("synth", ["--duration", "2"]), ("trace", ["--periods", "2", "--transient-periods", "0"])],
)
def test_an_output_given_positionally_or_as_minus_o_and_never_both(tmp_path, command, extra):
    first, second = tmp_path / "a.parquet", tmp_path / "b.parquet"
    new = CliRunner().invoke(main, [command, "-o", str(first), *extra])
    assert new.exit_code == 0 and first.exists(), new.output
    old = CliRunner().invoke(main, [command, str(second), *extra])
    assert old.exit_code == 0 and second.exists(), old.output
    both = CliRunner().invoke(main, [command, str(first), "-o", str(second), *extra])
    assert both.exit_code == 2 and "give the output once" in both.output
    neither = CliRunner().invoke(main, [command, *extra])
    assert neither.exit_code == 2 and "give -o/--output FILE" in neither.output
    assert len(neither.output.strip().splitlines()) == 1


def test_continue_takes_output_and_its_old_json_with_a_warning(tmp_path):
    args = ["continue", "alpha", "--from", "30", "--to", "30.5", "--max-points", "2"]
    new = CliRunner().invoke(main, [*args, "-o", str(tmp_path / "a.json")])
    assert new.exit_code == 0, new.output
    assert (tmp_path / "a.json").exists()
    old = CliRunner().invoke(main, [*args, "--json", str(tmp_path / "b.json")])
    assert old.exit_code == 0, old.output
    assert (tmp_path / "b.json").exists() and "deprecated" in old.output.lower()
