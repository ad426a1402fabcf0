"""Sweep commands: ``alpha``, ``fe``, ``mass``, ``sweep``, ``run``, ``plot``, ``figures``, ``params``."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import click

from ..backends import BACKENDS
from ..errors import ConfigError, ParameterError
from ..params import PARAM_SPECS, ModelParams
from ..sweep import DIRECTIONS, MODES, TRANSIENTS, SweepConfig, run_sweep, value_range
from ..gpu import DEVICES, with_device
from ._app import FINITE, main

#: ``--device`` of the commands that run independent emulated points in batches.
DEVICE_OPTION = click.option(
    "--device", type=click.Choice(DEVICES), default=None,
    help="Where batched emulated points integrate (fresh/multistart modes, Hopf simulate): cpu (default) or "
    "cuda, one NVIDIA GPU thread per point (pip install 'pendsweep[cuda]'; -B precision=float32 opts into single precision).",
)
from ._executor import apply_options, executor_options, max_work, work_options


def _key_value(pairs: tuple[str, ...], what: str) -> dict[str, str]:
    out = {}
    for pair in pairs:
        if "=" not in pair:
            raise ConfigError(f"{what} {pair!r} must look like NAME=VALUE")
        k, v = pair.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def load_model_file(path: Path) -> dict[str, float]:
    """A JSON object of ModelParams fields (e.g. written by ``pendsweep diagnose``)."""
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise ConfigError(f"no model file at {str(path)!r}") from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"model file {str(path)!r} is not valid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"model file {str(path)!r} must hold a JSON object of parameter values")
    params = data.get("params", data)
    ModelParams.from_mapping(params)  # validates names and ranges
    return {k: float(v) for k, v in params.items()}


def sweep_options(default_step: float, unit: str):
    """Options shared by the parameter-sweep commands."""

    def deco(fn):
        options = [
            click.option("--from", "start", type=FINITE, required=True, help=f"First value [{unit}]."),
            click.option("--to", "stop", type=FINITE, required=True, help=f"Last value [{unit}], included when on the grid."),
            click.option("--step", type=FINITE, default=None, help=f"Increment [{unit}] (default {default_step:g}; sign must match from -> to)."),
            click.option("--points", type=int, default=None, help="Number of values instead of --step (inclusive linspace)."),
            click.option("--alpha", type=FINITE, default=None, help="Forcing amplitude [N] (default 17)."),
            click.option("--fe", type=FINITE, default=None, help="Forcing frequency [Hz] (default 2.5)."),
            click.option("--M", "M_", type=FINITE, default=None, help="Oscillator mass M = M1 + M2 [kg] (default 10.9)."),
            click.option("--C", "C_", type=FINITE, default=None, help="Oscillator damping C = C1 + C2 [kg/s] (default 20)."),
            click.option("--K", "K_", type=FINITE, default=None, help="Oscillator stiffness [N/m] (default 1910)."),
            click.option("--set", "sets", multiple=True, metavar="NAME=VALUE", help="Any other model parameter, SI units (see `pendsweep params`)."),
            click.option("--model", "model_file", type=click.Path(dir_okay=False, path_type=Path), default=None, help="JSON file of model parameters (e.g. an extended model from `pendsweep diagnose`)."),
            click.option("--mode", type=click.Choice(MODES), default="continue", show_default=True, help="continue: carry the state (kick 0.1 rad when at rest); fresh: same start every point; multistart: --starts seeded starts per point."),
            click.option("--direction", type=click.Choice(DIRECTIONS), default="up", show_default=True, help="Traversal of continue branches; both exposes hysteresis."),
            click.option("--backend", type=click.Choice(sorted(BACKENDS)), default="emulated", show_default=True, help="Simulation backend."),
            click.option("-B", "--backend-option", "backend_opts", multiple=True, metavar="KEY=VALUE", help="Backend option, e.g. -B signum=stage."),
            DEVICE_OPTION,
            click.option("--dt", type=FINITE, default=None, help="Integration / controller step [s] (default 0.001)."),
            click.option("--transient-periods", type=int, default=100, show_default=True, help="Forcing periods discarded at each point (with --transient fixed)."),
            click.option("--transient", type=click.Choice(TRANSIENTS), default="fixed", show_default=True, help="fixed: discard --transient-periods (the paper); auto: integrate each point until its section repeats (n <= 8 periods, 1e-3) or its rotation number is steady, then record; rows gain settled, transient_periods_used."),
            click.option("--max-transient-periods", type=int, default=1000, show_default=True, help="Cap of --transient auto [forcing periods]."),
            click.option("--record-periods", type=int, default=20, show_default=True, help="Forcing periods recorded at each point."),
            click.option("--theta0", type=FINITE, default=0.1, show_default=True, help="Initial pendulum angle [rad]."),
            click.option("--thetadot0", type=FINITE, default=0.0, show_default=True, help="Initial pendulum rate [rad/s]."),
            click.option("--kick", type=FINITE, default=0.1, show_default=True, help="Angle [rad] added when the pendulum is at rest (continue mode)."),
            click.option("--rest-threshold", type=FINITE, default=0.0013, show_default=True, help="At rest: max|theta| below this [rad] (one encoder pulse)."),
            click.option("--starts", type=int, default=8, show_default=True, help="Initial conditions per point in multistart mode."),
            click.option("--seed", type=int, default=0, show_default=True, help="Seed of every random source."),
            click.option("-j", "--jobs", type=int, default=-1, show_default=True, help="Parallel workers for independent branches/points (-1: all cores)."),
            *executor_options(),
            *work_options(),
            click.option("-o", "--output", type=click.Path(path_type=Path), default=None, help="Results parquet (default results/<parameter>.parquet)."),
            click.option("--overwrite", is_flag=True, help="Replace earlier results at --output instead of resuming."),
            click.option("--plot", "plot_path", type=click.Path(path_type=Path), default=None, help="Also draw the bifurcation diagram here (.png/.pdf)."),
            click.option("--progress/--no-progress", default=None, help="Progress bar on stderr (default: when stderr is a terminal)."),
        ]
        for opt in reversed(options):
            fn = opt(fn)
        return fn

    return deco


def build_config(parameter: str, default_step: float, kw: dict[str, Any]) -> SweepConfig:
    """SweepConfig from the shared sweep options."""
    step = kw["step"]
    if step is None and kw["points"] is None:
        step = default_step if kw["stop"] >= kw["start"] else -default_step
    values = value_range(kw["start"], kw["stop"], step, kw["points"])
    model: dict[str, Any] = {}
    if kw["model_file"] is not None:
        model.update(load_model_file(kw["model_file"]))
    for name, key in (("alpha", "alpha"), ("fe", "fe"), ("M", "M_"), ("C", "C_"), ("K", "K_")):
        if kw[key] is not None:
            model[name] = kw[key]
    model.update({k: _finite(k, v) for k, v in _key_value(kw["sets"], "--set").items()})
    for name in model:
        if name not in PARAM_SPECS:
            raise ParameterError(f"unknown parameter {name!r}; known: {', '.join(PARAM_SPECS)}")
    backend_options = _key_value(kw["backend_opts"], "--backend-option")
    if kw["dt"] is not None:
        backend_options["dt"] = kw["dt"]
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
        transient=kw["transient"],
        max_transient_periods=kw["max_transient_periods"],
        initial=(0.0, 0.0, kw["theta0"], kw["thetadot0"]),
        kick=kw["kick"],
        rest_threshold=kw["rest_threshold"],
        starts=kw["starts"] if kw["mode"] == "multistart" else 1,
        seed=kw["seed"],
    )


def _finite(name: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ParameterError(f"--set {name}={text!r}: value is not a number") from None


def execute(
    config: SweepConfig,
    output: Path,
    *,
    jobs: int,
    overwrite: bool,
    progress: bool | None,
    plot_path: Path | None,
    title: str | None = None,
    executor: str = "local",
    scheduler: str | None = None,
    work_limit: float | None = None,
) -> None:
    """Run a sweep (on ``executor``), print a summary, optionally plot."""
    from ..executors import make_executor
    from ..plotting import plot_files

    if progress is None:
        progress = sys.stderr.isatty()
    if output.exists() and not overwrite:
        click.echo(f"{output} exists: reusing it if its configuration matches (--overwrite recomputes)")
    t0 = time.perf_counter()
    runner = make_executor(executor, scheduler)
    try:
        df = run_sweep(config, output, n_jobs=jobs, progress=progress, overwrite=overwrite, executor=runner,
                       max_work=work_limit)
    finally:
        runner.close()
    elapsed = time.perf_counter() - t0
    units = df.groupby(["direction", "point", "start"])["status"].first()
    counts = ", ".join(f"{n} {s}" for s, n in units.value_counts().items())
    click.echo(f"{len(units)} points ({counts}) in {elapsed:.2f} s -> {output}")
    if plot_path is not None:
        click.echo(f"plot -> {plot_files([output], plot_path, title=title)}")


def _sweep_command(name: str, parameter: str, default_step: float, help_text: str):
    unit = PARAM_SPECS[parameter].unit

    @main.command(name, help=help_text)
    @sweep_options(default_step, unit)
    def command(**kw):
        config = build_config(parameter, default_step, kw)
        output = kw["output"] or Path(f"results/{parameter}.parquet")
        execute(config, output, jobs=kw["jobs"], overwrite=kw["overwrite"], progress=kw["progress"], plot_path=kw["plot_path"],
                executor=kw["executor"], scheduler=kw["scheduler"], work_limit=max_work(kw["max_work"], kw["yes"]))

    return command


_sweep_command(
    "alpha", "alpha", 0.5,
    "Sweep the forcing amplitude alpha [N].\n\nExample (Fig. 11(a)): pendsweep alpha --from 0 --to 45",
)
_sweep_command(
    "fe", "fe", 0.01,
    "Sweep the forcing frequency fe [Hz].\n\nExample: pendsweep fe --from 2.0 --to 2.6 --alpha 17",
)
_sweep_command(
    "mass", "M", 0.1,
    "Sweep the oscillator mass M = M1 + M2 [kg].\n\nExample (Fig. 11(b)): pendsweep mass --from 0.1 --to 13 --alpha 17",
)


@main.command("sweep")
@click.argument("parameter")
@sweep_options(1.0, "parameter units")
def sweep_any(parameter, **kw):
    """Sweep any model PARAMETER (see `pendsweep params` for names and units).

    Example: pendsweep sweep K --from 1500 --to 2500 --step 10
    """
    if parameter not in PARAM_SPECS:
        raise ParameterError(f"unknown parameter {parameter!r}; steppable: {', '.join(PARAM_SPECS)}")
    if kw["step"] is None and kw["points"] is None:
        raise ConfigError("give --step or --points for a generic sweep")
    config = build_config(parameter, 1.0, kw)
    output = kw["output"] or Path(f"results/{parameter}.parquet")
    execute(config, output, jobs=kw["jobs"], overwrite=kw["overwrite"], progress=kw["progress"], plot_path=kw["plot_path"],
            executor=kw["executor"], scheduler=kw["scheduler"], work_limit=max_work(kw["max_work"], kw["yes"]))


@main.command("run")
@click.argument("definition", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None, help="Results parquet (default: the file's `output`).")
@click.option("--plot/--no-plot", "do_plot", default=True, show_default=True, help="Draw the file's `plot` after the sweep.")
@click.option("-j", "--jobs", type=int, default=-1, show_default=True, help="Parallel workers (-1: all cores).")
@click.option("--overwrite", is_flag=True, help="Replace earlier results instead of resuming.")
@click.option("--progress/--no-progress", default=None, help="Progress bar on stderr (default: when a terminal).")
@apply_options(executor_options() + work_options())
def run_definition(definition, output, do_plot, jobs, overwrite, progress, executor, scheduler, max_work, yes):
    """Run a declarative sweep (sweeps/NAME.toml), or regenerate a results parquet from its own metadata.

    Example: pendsweep run sweeps/fig11a.toml
    """
    from ..results import read_metadata
    from ..sweepfile import load_sweep

    if definition.suffix == ".parquet":
        meta = read_metadata(definition)
        config = SweepConfig.from_dict(meta["config"])
        if output is None:
            raise ConfigError("regenerating from a parquet needs -o/--output for the new file")
        plot_path, title = None, None
    else:
        spec = load_sweep(definition)
        config, output = spec.config, output or spec.output
        plot_path = spec.plot if do_plot else None
        title = spec.description or None
    execute(config, output, jobs=jobs, overwrite=overwrite, progress=progress, plot_path=plot_path, title=title,
            executor=executor, scheduler=scheduler, work_limit=None if yes else max_work)


@main.command("plot", short_help="Draw a Fig. 11-style bifurcation diagram.")
@click.argument("results", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None, help="Figure file, .png/.pdf/.svg (default: first input with .png).")
@click.option("--observable", type=click.Choice(["theta_peak", "theta_absmax", "theta_sec", "y_absmax"]), default="theta_peak", show_default=True, help="Quantity on the vertical axis (angles in rad, y in m).")
@click.option("--title", default=None, help="Figure title.")
def plot_command(results, output, observable, title):
    """Draw a Fig. 11-style bifurcation diagram of one or more result files.

    Overlaying up, down and multistart files shows hysteresis and coexisting attractors.
    Continuation results (.json from `pendsweep continue`) are drawn on top as branches:
    solid stable, dashed unstable, markers at bifurcations.
    """
    from ..continuation.overlay import plot_any

    output = output or Path(results[0]).with_suffix(".png")
    click.echo(f"plot -> {plot_any(list(results), output, observable, title)}")


@main.command("figures")
@click.argument("names", nargs=-1)
@click.option("--out", "outdir", type=click.Path(file_okay=False, path_type=Path), default=Path("results/figures"), show_default=True, help="Output folder.")
@click.option("--quick", is_flag=True, help="Small, fast versions (smoke test).")
def figures_command(names, outdir, quick):
    """Regenerate the paper's figures (all, or the NAMES given)."""
    from ..figures import FIGURES, make_figures

    if not names:
        click.echo(f"figures: {', '.join(FIGURES)}")
    for path in make_figures(list(names), outdir, quick):
        click.echo(f"wrote {path}")


@main.command("params")
def params_command():
    """List model parameters with units, accepted ranges and defaults."""
    defaults = ModelParams().to_dict()
    defaults.update(M1=ModelParams().M1, C1=ModelParams().C1)
    click.echo(f"{'name':6} {'default':>12} {'unit':12} {'range':16} meaning")
    for name, spec in PARAM_SPECS.items():
        click.echo(f"{name:6} {defaults[name]:>12.6g} {spec.unit:12} {spec.describe_range():16} {spec.doc}")
