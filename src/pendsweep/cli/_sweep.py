"""Sweep commands: ``alpha``, ``fe``, ``mass``, ``sweep``, ``run``, ``plot``, ``figures``, ``params``."""

from __future__ import annotations

import collections
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import click

from ..errors import ConfigError, ParameterError, PendsweepError
from ..params import PARAM_SPECS, ModelParams
from ..sweepfile import MAX_POINTS, MAX_STARTS, describe_count, grid_size
from ._app import ANGLE, FINITE, PATH, PERIODS, RATE, SEED, SMALL_ANGLE, STEP_S, LazyChoice, given, main
from ._checks import FIGURE_SUFFIXES, check_input, check_output, check_output_dir, key_values, model_sets
from ._executor import apply_options, checkpoint_option, executor_options, max_work, work_options


def load_model_file(path: Path) -> dict[str, float]:
    """A JSON object of ModelParams fields (e.g. written by ``pendsweep diagnose``)."""
    name = str(path)
    check_input(path, "model file")
    try:
        data = json.loads(Path(path).read_bytes().decode("utf-8"))
    except UnicodeDecodeError:
        raise ConfigError(f"model file {name!r} is not a text (UTF-8) JSON file") from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"model file {name!r} is not valid JSON: {exc}") from None
    params = data.get("params", data) if isinstance(data, dict) else data
    if not isinstance(params, dict):
        raise ConfigError(
            f"model file {name!r} must hold a JSON object of parameter values, not {type(params).__name__}"
        )
    for key, value in params.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(f"model file {name!r}: {key} = {value!r} must be a finite number")
    ModelParams.from_mapping(params)  # validates names and ranges
    return {k: float(v) for k, v in params.items()}


#: The options that fix one model parameter, as (parameter, option, click name).
FIXED_OPTIONS = (
    ("alpha", "--alpha", "alpha"),
    ("fe", "--fe", "fe"),
    ("M", "--M", "M_"),
    ("C", "--C", "C_"),
    ("K", "--K", "K_"),
)


#: ``--device`` of the commands that run independent emulated points in batches.
DEVICE_OPTION = click.option(
    "--device",
    type=LazyChoice(".gpu", "DEVICES"),
    default=None,
    help="Where batched emulated points integrate (fresh/multistart modes, Hopf simulate): cpu (default) or "
    "cuda, one NVIDIA GPU thread per point (pip install 'pendsweep[cuda]'; -B precision=float32 opts into single precision).",
)


def sweep_options(default_step: float, unit: str):
    """Options shared by the parameter-sweep commands."""

    def deco(fn):
        options = [
            click.option("--from", "start", type=FINITE, required=True, help=f"First value [{unit}]."),
            click.option(
                "--to", "stop", type=FINITE, required=True, help=f"Last value [{unit}], included when on the grid."
            ),
            click.option(
                "--step",
                type=FINITE,
                default=None,
                help=f"Increment [{unit}] (default {default_step:g}; sign must match from -> to; at most {MAX_POINTS} values).",
            ),
            click.option(
                "--points",
                type=click.IntRange(1, MAX_POINTS),
                default=None,
                help="Number of values instead of --step (inclusive linspace).",
            ),
            click.option("--alpha", type=FINITE, default=None, help="Forcing amplitude [N] (default 17)."),
            click.option("--fe", type=FINITE, default=None, help="Forcing frequency [Hz] (default 2.5)."),
            click.option(
                "--M", "M_", type=FINITE, default=None, help="Oscillator mass M = M1 + M2 [kg] (default 10.9)."
            ),
            click.option(
                "--C", "C_", type=FINITE, default=None, help="Oscillator damping C = C1 + C2 [kg/s] (default 20)."
            ),
            click.option("--K", "K_", type=FINITE, default=None, help="Oscillator stiffness [N/m] (default 1910)."),
            click.option(
                "--set",
                "sets",
                multiple=True,
                metavar="NAME=VALUE",
                help="Any other model parameter, SI units (see `pendsweep params`).",
            ),
            click.option(
                "--model",
                "model_file",
                type=click.Path(dir_okay=False, path_type=Path),
                default=None,
                help="JSON file of model parameters (e.g. an extended model from `pendsweep diagnose`).",
            ),
            click.option(
                "--mode",
                type=LazyChoice(".sweep", "MODES"),
                default="continue",
                show_default=True,
                help="continue: carry the state (kick 0.1 rad when at rest); fresh: same start every point; multistart: --starts seeded starts per point.",
            ),
            click.option(
                "--direction",
                type=LazyChoice(".sweep", "DIRECTIONS"),
                default="up",
                show_default=True,
                help="Traversal of continue branches; both exposes hysteresis (continue mode only).",
            ),
            click.option(
                "--backend",
                type=LazyChoice(".backends", "BACKENDS"),
                default="emulated",
                show_default=True,
                help="Simulation backend.",
            ),
            click.option(
                "-B",
                "--backend-option",
                "backend_opts",
                multiple=True,
                metavar="KEY=VALUE",
                help="Backend option, e.g. -B signum=stage.",
            ),
            DEVICE_OPTION,
            click.option(
                "--dt",
                type=STEP_S,
                default=None,
                help="Integration / controller step [s], 1e-6 to 0.01 (default 0.001).",
            ),
            click.option(
                "--transient-periods",
                type=PERIODS,
                default=100,
                show_default=True,
                help="Forcing periods discarded at each point [-] (with --transient fixed).",
            ),
            click.option(
                "--transient",
                type=LazyChoice(".sweep", "TRANSIENTS"),
                default="fixed",
                show_default=True,
                help="fixed: discard --transient-periods (the paper); auto: integrate each point until its section "
                "repeats (n <= 8 periods, 1e-3) or its rotation number is steady, then record; rows gain settled, "
                "transient_periods_used.",
            ),
            click.option(
                "--max-transient-periods",
                type=click.IntRange(1, PERIODS.max),
                default=1000,
                show_default=True,
                help="Cap of --transient auto [forcing periods].",
            ),
            click.option(
                "--record-periods",
                type=click.IntRange(1, PERIODS.max),
                default=20,
                show_default=True,
                help="Forcing periods recorded at each point [-].",
            ),
            click.option(
                "--theta0",
                type=ANGLE,
                default=0.1,
                show_default=True,
                help="Initial pendulum angle [rad], within +-10 pi.",
            ),
            click.option(
                "--thetadot0",
                type=RATE,
                default=0.0,
                show_default=True,
                help="Initial pendulum rate [rad/s], within +-1000.",
            ),
            click.option(
                "--kick",
                type=SMALL_ANGLE,
                default=0.1,
                show_default=True,
                help="Angle [rad] added when the pendulum is at rest (continue mode only), 0 to pi.",
            ),
            click.option(
                "--rest-threshold",
                type=SMALL_ANGLE,
                default=0.0013,
                show_default=True,
                help="At rest: max|theta| below this [rad] (one encoder pulse), 0 to pi.",
            ),
            click.option(
                "--starts",
                type=click.IntRange(1, MAX_STARTS),
                default=8,
                show_default=True,
                help="Initial conditions per point (multistart mode only).",
            ),
            click.option(
                "--seed", type=SEED, default=0, show_default=True, help="Seed of every random source (0 to 2**63-1)."
            ),
            click.option(
                "-j",
                "--jobs",
                type=int,
                default=-1,
                show_default=True,
                help="Parallel workers for independent branches/points (-1: all cores).",
            ),
            *executor_options(),
            *work_options(),
            click.option(
                "-o",
                "--output",
                type=PATH,
                default=None,
                help="Results file, .parquet (default results/<parameter>.parquet, replaced when it holds another configuration).",
            ),
            click.option("--overwrite", is_flag=True, help="Replace earlier results at --output instead of resuming."),
            checkpoint_option(),
            click.option(
                "--plot",
                "plot_path",
                type=PATH,
                default=None,
                help="Also draw the bifurcation diagram here (.png/.pdf/.svg).",
            ),
            click.option(
                "--progress/--no-progress",
                default=None,
                help="Progress bar on stderr (default: when stderr is a terminal).",
            ),
        ]
        for opt in reversed(options):
            fn = opt(fn)
        return fn

    return deco


def refuse_inapplicable(ctx: click.Context, kw: dict[str, Any]) -> None:
    """Options that the chosen mode would ignore are errors, never stored as if they took effect."""
    mode = kw["mode"]
    if mode != "multistart" and given(ctx, "starts"):
        raise ConfigError(f"--starts {kw['starts']} applies only to --mode multistart (mode is {mode})")
    for name in ("direction", "kick"):
        if mode != "continue" and given(ctx, name):
            raise ConfigError(f"--{name} {kw[name]} applies only to --mode continue (mode is {mode})")
    if kw["transient"] == "auto" and given(ctx, "transient_periods"):
        raise ConfigError(f"--transient-periods {kw['transient_periods']} applies only to --transient fixed")
    if kw["transient"] == "fixed" and given(ctx, "max_transient_periods"):
        raise ConfigError(f"--max-transient-periods {kw['max_transient_periods']} applies only to --transient auto")


def build_config(parameter: str, default_step: float, kw: dict[str, Any], ctx: click.Context | None = None):
    """SweepConfig from the shared sweep options (every check that needs no simulation runs here)."""
    from ..sweep import SweepConfig, value_range

    if ctx is not None:
        refuse_inapplicable(ctx, kw)
    step = kw["step"]
    if step is not None and kw["points"] is not None:
        raise ConfigError(f"give --step or --points, not both (got --step {step:g} and --points {kw['points']})")
    if step is None and kw["points"] is None:
        step = default_step if kw["stop"] >= kw["start"] else -default_step
    count = grid_size(kw["start"], kw["stop"], step) if step else 0  # step 0 is refused by value_range
    if count > MAX_POINTS:
        raise ConfigError(
            f"--step {step:g} gives {describe_count(count)} from {kw['start']:g} to {kw['stop']:g}; "
            f"at most {MAX_POINTS:,}: use a larger step"
        )
    values = value_range(kw["start"], kw["stop"], step, kw["points"])
    model: dict[str, Any] = {}
    if kw["model_file"] is not None:
        from_file = load_model_file(kw["model_file"])
        if parameter in from_file:
            click.echo(
                f"note: the swept values replace {parameter} = {from_file.pop(parameter):g} from {kw['model_file']}",
                err=True,
            )
        model.update(from_file)
    options = {}
    for name, option, key in FIXED_OPTIONS:
        if kw[key] is not None:
            model[name] = kw[key]
            options[name] = option + " "
    sets = model_sets(kw["sets"])
    for name, value in sets.items():
        if name in options:
            raise ConfigError(f"{options[name].strip()} and --set {name}={value:g} both fix {name}; give one")
        options[name] = f"--set {name}="
    model.update(sets)
    if parameter in options:
        raise ConfigError(
            f"{options[parameter]}{model[parameter]:g} fixes the swept parameter {parameter!r}; "
            "drop it (--from/--to give its values)"
        )
    backend_options: dict[str, Any] = key_values(kw["backend_opts"], "--backend-option")
    if kw["dt"] is not None:
        backend_options["dt"] = kw["dt"]
    from ..gpu import with_device

    backend_options = with_device(kw["backend"], backend_options, kw["device"] or backend_options.get("device"))
    return SweepConfig(
        parameter=parameter,
        values=tuple(values),
        model=model,
        mode=kw["mode"],
        direction=kw["direction"],
        backend=kw["backend"],
        backend_options=backend_options,
        transient_periods=kw["transient_periods"],
        record_periods=kw["record_periods"],
        initial=(0.0, 0.0, kw["theta0"], kw["thetadot0"]),
        kick=kw["kick"],
        rest_threshold=kw["rest_threshold"],
        starts=kw["starts"] if kw["mode"] == "multistart" else 1,
        seed=kw["seed"],
        transient=kw["transient"],
        max_transient_periods=kw["max_transient_periods"],
    )


def prepare_output(output: Path, config_hash: str, *, default: bool, overwrite: bool) -> bool:
    """Decide what to do with results already at ``output``; returns the ``overwrite`` to run with.

    A *default* path is shared by every query of one kind (``results/alpha.parquet``,
    ``results/hopf.parquet``): finished results of another configuration there
    are replaced with a one-line note instead of failing a second, different
    query. The same configuration resumes (or is reused) as usual. An explicit
    ``-o`` is never replaced without ``--overwrite``; when it holds a file that
    cannot be read back as results, that is a runtime failure (exit 1).
    """
    from ..errors import CorruptResultsError
    from ..results import read_metadata

    if overwrite or not output.is_file():
        return overwrite
    try:
        held = read_metadata(output).get("config_hash")
    except (PendsweepError, ValueError, AttributeError) as exc:
        if not default:
            raise CorruptResultsError(
                f"{str(output)!r} exists but cannot be read back as results ({exc}); pass --overwrite to replace it"
            ) from None
        held = None
    if held == config_hash or not default:
        return False
    click.echo(f"note: {output} held results of another configuration; replacing them (give -o to keep both)", err=True)
    return True


def execute(
    config,
    output: Path,
    *,
    jobs: int,
    overwrite: bool,
    progress: bool | None,
    plot_path: Path | None,
    title: str | None = None,
    executor: str = "local",
    scheduler: str | None = None,
    default_output: bool = False,
    work_limit: float | None = None,
    checkpoint_seconds: float = 1.0,
) -> None:
    """Run a sweep (on ``executor``), print a summary, optionally plot.

    ``default_output`` marks an output path the user did not choose: finished
    results of another configuration there are replaced (with a note).
    """
    from ..executors import make_executor
    from ..sweep import run_sweep, sweep_metadata

    check_output(output, "-o/--output", (".parquet",))
    check_output(plot_path, "--plot", FIGURE_SUFFIXES)
    if progress is None:
        progress = sys.stderr.isatty()
    overwrite = prepare_output(
        output, sweep_metadata(config)["config_hash"], default=default_output, overwrite=overwrite
    )
    if output.exists() and not overwrite:
        click.echo(f"{output} exists: reusing it if its configuration matches (--overwrite recomputes)")
    t0 = time.perf_counter()
    runner = make_executor(executor, scheduler)
    try:
        rows = run_sweep(
            config,
            output,
            n_jobs=jobs,
            progress=progress,
            overwrite=overwrite,
            executor=runner,
            max_work=work_limit,
            as_frame=False,
            checkpoint_seconds=checkpoint_seconds,
        )
    finally:
        runner.close()
    elapsed = time.perf_counter() - t0
    click.echo(f"{unit_summary(rows)} in {elapsed:.2f} s -> {output}")
    if plot_path is not None:
        from ..plotting import plot_files

        click.echo(f"plot -> {plot_files([output], plot_path, title=title)}")


def unit_summary(rows) -> str:
    """``"91 points (80 ok, 11 diverged)"``: units (direction, point, start) by status, most common first.

    ``rows`` is a sweep's pyarrow Table; a unit's status is the same on all its rows.
    """
    if not rows.num_rows:
        return "0 points ()"
    from ..columns import to_numpy

    first = to_numpy(rows["period"]) == 0
    statuses = collections.Counter(s for s, f in zip(rows["status"].to_pylist(), first) if f)
    counts = ", ".join(f"{n} {s}" for s, n in statuses.most_common())
    return f"{int(first.sum())} points ({counts})"


def _run_options(kw: dict[str, Any]) -> dict[str, Any]:
    return dict(jobs=kw["jobs"], overwrite=kw["overwrite"], progress=kw["progress"], plot_path=kw["plot_path"],
                executor=kw["executor"], scheduler=kw["scheduler"], default_output=kw["output"] is None,
                work_limit=max_work(kw["max_work"], kw["yes"]), checkpoint_seconds=kw["checkpoint_seconds"])  # fmt: skip


def _sweep_command(name: str, parameter: str, default_step: float, help_text: str):
    unit = PARAM_SPECS[parameter].unit

    @main.command(name, help=help_text)
    @sweep_options(default_step, unit)
    @click.pass_context
    def command(ctx, **kw):
        config = build_config(parameter, default_step, kw, ctx)
        execute(config, kw["output"] or Path(f"results/{parameter}.parquet"), **_run_options(kw))

    return command


_sweep_command(
    "alpha",
    "alpha",
    0.5,
    "Sweep the forcing amplitude alpha [N].\n\nExample (Fig. 11(a)): pendsweep alpha --from 0 --to 45",
)
_sweep_command(
    "fe",
    "fe",
    0.01,
    "Sweep the forcing frequency fe [Hz].\n\nExample: pendsweep fe --from 2.0 --to 2.6 --alpha 17",
)
_sweep_command(
    "mass",
    "M",
    0.1,
    "Sweep the oscillator mass M = M1 + M2 [kg].\n\nExample (Fig. 11(b)): pendsweep mass --from 0.1 --to 13 --alpha 17",
)


@main.command("sweep")
@click.argument("parameter")
@sweep_options(1.0, "parameter units")
@click.pass_context
def sweep_any(ctx, parameter, **kw):
    """Sweep any model PARAMETER (see `pendsweep params` for names and units).

    Example: pendsweep sweep K --from 1500 --to 2500 --step 10
    """
    if parameter not in PARAM_SPECS:
        raise ParameterError(f"unknown parameter {parameter!r}; steppable: {', '.join(PARAM_SPECS)}")
    if kw["step"] is None and kw["points"] is None:
        raise ConfigError(f"give --step or --points for a generic sweep of {parameter!r}")
    config = build_config(parameter, 1.0, kw, ctx)
    execute(config, kw["output"] or Path(f"results/{parameter}.parquet"), **_run_options(kw))


def read_sweep_metadata(path: Path, option: str = "RESULTS") -> dict[str, Any]:
    """The metadata of a sweep result file; any other file is refused, naming what it is."""
    from ..results import read_metadata

    check_input(path, "results file")
    try:
        meta = read_metadata(path)
    except ValueError as exc:  # JSON that is not JSON
        raise ConfigError(f"{option} {str(path)!r}: its pendsweep metadata is not valid JSON ({exc})") from None
    kind = meta.get("kind") if isinstance(meta, dict) else None
    if kind != "sweep" or not isinstance(meta.get("config"), dict):
        what = {
            "hopf": "a Hopf scan from `pendsweep hopf`",
            "trace": "a time series from `pendsweep trace`",
            "free_decay": "a measured-data record",
            "forced": "a measured-data record",
            "substructured": "a measured-data record",
        }.get(kind, f"a file of kind {kind!r}")
        raise ConfigError(
            f"{option} {str(path)!r} is {what}, not sweep results from `pendsweep alpha/fe/mass/sweep/run`"
        )
    return meta


def _list_builtin() -> None:
    from ..sweepfile import builtin_sweeps, load_sweep

    for name, path in builtin_sweeps().items():
        click.echo(f"{name:10} {load_sweep(path).description}")


@main.command("run")
@click.argument("definition", required=False, type=PATH)
@click.option("--list", "list_builtin", is_flag=True, help="List the built-in sweep definitions and stop.")
@click.option(
    "-o",
    "--output",
    type=PATH,
    default=None,
    help="Results file, .parquet (default: the definition's `output`).",
)
@click.option(
    "--plot/--no-plot", "do_plot", default=True, show_default=True, help="Draw the definition's `plot` after the sweep."
)
@click.option("-j", "--jobs", type=int, default=-1, show_default=True, help="Parallel workers (-1: all cores).")
@click.option("--overwrite", is_flag=True, help="Replace earlier results instead of resuming.")
@checkpoint_option()
@click.option("--progress/--no-progress", default=None, help="Progress bar on stderr (default: when a terminal).")
@apply_options(executor_options() + work_options())
def run_definition(
    definition,
    list_builtin,
    output,
    do_plot,
    jobs,
    overwrite,
    checkpoint_seconds,
    progress,
    executor,
    scheduler,
    max_work,
    yes,
):
    """Run a declarative sweep: a built-in NAME (see --list), a TOML file, or a results parquet to regenerate.

    Examples: pendsweep run fig11a; pendsweep run my-sweep.toml;
    pendsweep run results/fig11a.parquet -o copy.parquet
    """
    from ..sweepfile import load_sweep

    if list_builtin:
        _list_builtin()
        return
    if definition is None:
        raise ConfigError("give a sweep: a built-in name (pendsweep run --list), a .toml file or a results .parquet")
    if definition.suffix == ".parquet":
        from ..sweep import SweepConfig

        meta = read_sweep_metadata(definition, "DEFINITION")
        if output is None:
            raise ConfigError("regenerating from a parquet needs -o/--output for the new file")
        if output.resolve() == definition.resolve():
            raise ConfigError(f"-o {str(output)!r} is the results file being regenerated; give another path")
        try:
            config = SweepConfig.from_dict(meta["config"])
        except (TypeError, KeyError) as exc:
            raise ConfigError(
                f"DEFINITION {str(definition)!r}: its stored configuration is not a sweep's ({exc})"
            ) from None
        plot_path, title, default_output = None, None, False
    else:
        spec = load_sweep(definition)
        config, default_output = spec.config, output is None
        output = output or spec.output
        plot_path = spec.plot if do_plot else None
        title = spec.description or None
    execute(config, output, jobs=jobs, overwrite=overwrite, progress=progress, plot_path=plot_path, title=title,
            executor=executor, scheduler=scheduler, default_output=default_output,
            work_limit=None if yes else max_work, checkpoint_seconds=checkpoint_seconds)  # fmt: skip


@main.command("plot", short_help="Draw a Fig. 11-style bifurcation diagram.")
@click.argument("results", nargs=-1, required=True, type=PATH)
@click.option(
    "-o",
    "--output",
    type=PATH,
    default=None,
    help="Figure file, .png/.pdf/.svg (default: first input with .png).",
)
@click.option(
    "--observable",
    type=click.Choice(["theta_peak", "theta_absmax", "theta_sec", "y_absmax"]),
    default="theta_peak",
    show_default=True,
    help="Quantity on the vertical axis (angles in rad, y in m).",
)
@click.option("--title", default=None, help="Figure title.")
def plot_command(results, output, observable, title):
    """Draw a Fig. 11-style bifurcation diagram of one or more result files.

    Overlaying up, down and multistart files shows hysteresis and coexisting attractors.
    Continuation results (.json from `pendsweep continue`) are drawn on top as branches:
    solid stable, dashed unstable, markers at bifurcations.
    """
    from ..continuation.overlay import plot_any

    for path in results:
        if path.suffix == ".json":
            check_continuation_document(path)
        else:
            read_sweep_metadata(path)
    output = check_output(output or Path(results[0]).with_suffix(".png"), "-o/--output", FIGURE_SUFFIXES)
    click.echo(f"plot -> {plot_any(list(results), output, observable, title)}")


def check_continuation_document(path: Path) -> None:
    """Refuse a ``.json`` that is not a readable continuation result, naming it."""
    from ..continuation.run import read_json

    check_input(path, "continuation result")
    try:
        path.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError(f"{str(path)!r} is not a text (UTF-8) JSON file") from None
    read_json(path)


@main.command("figures")
@click.argument("names", nargs=-1)
@click.option(
    "-o",
    "--output",
    "outdir",
    type=PATH,
    default=None,
    help="Output folder [default: results/figures].",
)
@click.option("--out", "outdir_old", type=PATH, default=None, hidden=True, deprecated="use -o/--output")
@click.option("--quick", is_flag=True, help="Small, fast versions (smoke test).")
def figures_command(names, outdir, outdir_old, quick):
    """Regenerate the paper's figures (all, or the NAMES given; e.g. pendsweep figures fig8 fig9)."""
    from ..figures import FIGURES, make_figures

    if outdir is not None and outdir_old is not None:
        raise ConfigError("give the output folder once (-o/--output; --out is its old name)")
    outdir = check_output_dir(outdir or outdir_old or Path("results/figures"), "-o/--output")
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise ConfigError(f"unknown figure(s) {', '.join(unknown)}; choose from {', '.join(FIGURES)}")
    if not names:
        click.echo(f"figures: {', '.join(FIGURES)}")
    for name in names or FIGURES:
        written = make_figures([name], outdir, quick)
        for path in written:
            click.echo(f"wrote {path}")
        if not written:
            from ..data import DATA_ENV

            click.echo(f"{name}: skipped, its measured data were not found (set {DATA_ENV} to the folder holding "
                       "measured/free-swing-rotary-pendulum)", err=True)  # fmt: skip


@main.command("params")
def params_command():
    """List model parameters with units, accepted ranges and defaults."""
    defaults = ModelParams().to_dict()
    defaults.update(M1=ModelParams().M1, C1=ModelParams().C1)
    click.echo(f"{'name':6} {'default':>12} {'unit':12} {'range':16} meaning")
    for name, spec in PARAM_SPECS.items():
        click.echo(f"{name:6} {defaults[name]:>12.6g} {spec.unit:12} {spec.describe_range():16} {spec.doc}")
