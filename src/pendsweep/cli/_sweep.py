"""Sweep commands: ``alpha``, ``fe``, ``mass``, ``sweep`` and ``run``: prepare the output, run, summarise."""

from __future__ import annotations

import collections
import sys
import time
from pathlib import Path
from typing import Any

import click

from ..errors import ConfigError, ParameterError, PendsweepError
from ..model.params import PARAM_SPECS
from ._app import PATH, main
from ._checks import FIGURE_SUFFIXES, check_input, check_output
from ._executor import apply_options, checkpoint_option, executor_options, max_work, work_options
from ._sweep_options import build_config, sweep_options


def prepare_output(output: Path, config_hash: str, *, default: bool, overwrite: bool) -> bool:
    """Decide what to do with results already at ``output``; returns the ``overwrite`` to run with.

    A *default* path is shared by every query of one kind (``results/alpha.parquet``,
    ``results/hopf.parquet``): finished results of another configuration there
    are replaced with a one-line note instead of failing a second, different
    query. The same configuration resumes (or is reused) as usual. An explicit
    ``-o`` is never replaced without ``--overwrite``; when it holds a file that
    cannot be read back as results, that is a runtime failure (exit 1).
    """
    from ..engine.results import read_metadata
    from ..errors import CorruptResultsError

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
    stop_periods: int = 5,
) -> None:
    """Run a sweep (on ``executor``), print a summary, optionally plot.

    ``default_output`` marks an output path the user did not choose: finished
    results of another configuration there are replaced (with a note). A
    remote rig's continuous test (continue mode) keeps its time series beside
    ``output``, redraws ``plot_path`` after every point and ramps down over
    ``stop_periods`` on a safe stop (:mod:`pendsweep.studies.rig_sweep`).
    """
    from ..engine.executors import make_executor
    from ..engine.scan import check_jobs
    from ..studies.sweep import run_sweep, sweep_metadata

    check_jobs(jobs)  # before the output is looked at, so a bad -j prints no note about it
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
    rig_test = bool(config.backend_options.get("rig")) and config.mode == "continue"
    watch = None
    if rig_test:
        from ..studies.rig_sweep import RigWatch, default_watch

        watch = default_watch(RigWatch(plot=plot_path, stop_periods=stop_periods), output)
        progress = False  # one line per point instead of a bar
    runner = make_executor(executor, scheduler)
    try:
        rows = _run_sweep_stopping_safely(
            run_sweep,
            config,
            output,
            n_jobs=jobs,
            progress=progress,
            overwrite=overwrite,
            executor=runner,
            max_work=work_limit,
            as_frame=False,
            checkpoint_seconds=checkpoint_seconds,
            watch=watch,
        )
    finally:
        runner.close()
    elapsed = time.perf_counter() - t0
    click.echo(f"{unit_summary(rows)} in {elapsed:.2f} s -> {output}")
    if watch is not None and watch.timeseries is not None:
        click.echo(f"time series -> {watch.timeseries}")
    if plot_path is not None and watch is not None:
        click.echo(f"plot -> {plot_path} (redrawn after every point)")
    elif plot_path is not None:
        from ..figures.plotting import plot_files

        click.echo(f"plot -> {plot_files([output], plot_path, title=title)}")


def _run_sweep_stopping_safely(run_sweep, *args, **kwargs):
    """``run_sweep``, with a rig test's safe stop told that its finished points are kept for a resume."""
    from ..hybrid.session import RigStopped

    try:
        return run_sweep(*args, **kwargs)
    except RigStopped as exc:
        raise RigStopped(f"{exc}; finished points are kept: the same command resumes", exc.exit_code) from None


def unit_summary(rows) -> str:
    """``"91 points (80 ok, 11 diverged)"``: units (direction, point, start) by status, most common first.

    ``rows`` is a sweep's pyarrow Table; a unit's status is the same on all its rows.
    """
    if not rows.num_rows:
        return "0 points ()"
    from ..engine.columns import to_numpy

    first = to_numpy(rows["period"]) == 0
    statuses = collections.Counter(s for s, f in zip(rows["status"].to_pylist(), first) if f)
    counts = ", ".join(f"{n} {s}" for s, n in statuses.most_common())
    return f"{int(first.sum())} points ({counts})"


def _run_options(kw: dict[str, Any]) -> dict[str, Any]:
    return dict(jobs=kw["jobs"], overwrite=kw["overwrite"], progress=kw["progress"], plot_path=kw["plot_path"],
                executor=kw["executor"], scheduler=kw["scheduler"], default_output=kw["output"] is None,
                work_limit=max_work(kw["max_work"], kw["yes"]), checkpoint_seconds=kw["checkpoint_seconds"],
                stop_periods=kw["stop_periods"])  # fmt: skip


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
    from ..engine.results import read_metadata

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
    from ..studies.sweepfile import builtin_sweeps, load_sweep

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
    from ..studies.sweepfile import load_sweep

    if list_builtin:
        _list_builtin()
        return
    if definition is None:
        raise ConfigError("give a sweep: a built-in name (pendsweep run --list), a .toml file or a results .parquet")
    if definition.suffix == ".parquet":
        from ..studies.sweep import SweepConfig

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
