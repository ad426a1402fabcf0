"""``pendsweep curve`` and ``pendsweep tolerance``: bifurcation curves in two parameters."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ..errors import ConfigError
from ._app import FINITE, main
from ._checks import FIGURE_SUFFIXES, backend_option, check_output, key_values

_PROGRESS = click.option(
    "--progress/--no-progress", default=None, help="Progress bar on stderr (default: when stderr is a terminal)."
)


def _steps(f):
    for option in reversed(
        [
            click.option(
                "--ds", type=FINITE, default=0.02, show_default=True, help="First arclength step [-] (scaled)."
            ),
            click.option("--ds-max", type=FINITE, default=0.1, show_default=True, help="Largest arclength step [-]."),
            click.option(
                "--max-points",
                type=click.IntRange(min=1),
                default=200,
                show_default=True,
                help="Points per direction of each curve.",
            ),
            click.option(
                "--tol",
                "newton_tol",
                type=FINITE,
                default=1e-9,
                show_default=True,
                help="Newton tolerance on the scaled update and residual [-].",
            ),
        ]
    ):
        f = option(f)
    return f


@main.command("curve")
@click.argument("start", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--bifurcation",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Which bifurcation of START's list (as `continue` prints them, from 0).",
)
@click.option("--second", required=True, help="The second parameter (a model parameter; the loop's options too).")
@click.option(
    "--from", "start_value", type=FINITE, required=True, help="Start of the second parameter's interval [its unit]."
)
@click.option(
    "--to", "stop_value", type=FINITE, required=True, help="End of the second parameter's interval [its unit]."
)
@click.option(
    "--limits",
    type=(FINITE, FINITE),
    default=None,
    help="Interval of the first parameter [its unit] (default: START's interval widened by its length each side).",
)
@_steps
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Result parquet (default results/curve-FIRST-SECOND.parquet).")  # fmt: skip
@click.option("--resume", is_flag=True, help="Go on from an unfinished result of the same configuration at -o.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also draw the curve (.png/.pdf/.svg).")  # fmt: skip
@click.option(
    "--overlay",
    "overlays",
    multiple=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Under --plot: a `pendsweep map` result over the same parameters, or other curve results (repeatable).",
)
@_PROGRESS
def curve_command(
    start, bifurcation, second, start_value, stop_value, limits, ds, ds_max, max_points, newton_tol, output,
    resume, plot_path, overlays, progress,
):  # fmt: skip
    """Trace a fold, period-doubling or Neimark-Sacker point of START (a `continue` result) in a second parameter.

    The curve of the orbit's bifurcation in (START's parameter, --second),
    both ways from the point, for the emulated system or the hybrid loop
    (whatever START continued). Located on the way: turns in either
    parameter, cusps, degenerate period doublings, 1:1, 1:2, 1:3 and 1:4
    resonances and the points where it meets another curve (fold-flip,
    fold-NS, flip-NS). Exit 1 when the point does not converge at its start.
    """
    from ..analysis.continuation import ContinuationError
    from ..analysis.continuation.curve_run import config_from_file, curve_events, run_curve

    config = config_from_file(
        start,
        bifurcation,
        second=second,
        start=start_value,
        stop=stop_value,
        first_limits=limits,
        ds=ds,
        ds_max=ds_max,
        max_points=max_points,
        newton_tol=newton_tol,
    )
    output = check_output(
        output or Path(f"results/curve-{config.first}-{second}.parquet"), "-o/--output", (".parquet",)
    )
    check_output(plot_path, "--plot", FIGURE_SUFFIXES)
    if overlays:
        if plot_path is None:
            raise ConfigError("--overlay draws under --plot: give --plot FILE too")
        from ..figures.curves import check_overlays

        check_overlays((config.first, second), list(overlays))
    progress = sys.stderr.isatty() if progress is None else progress
    try:
        rows = run_curve(config, output, progress=progress, resume=resume)
    except ContinuationError as exc:
        raise click.ClickException(str(exc)) from None
    from ..engine.results import read_metadata

    ends = read_metadata(output)["ends"]
    first, kind = config.first, config.kind
    click.echo(
        f"{kind} curve: {len(rows)} points, {second} {rows[second].min():.6g} to {rows[second].max():.6g}, "
        f"{first} {rows[first].min():.6g} to {rows[first].max():.6g}; ends: {ends[0]}, {ends[1]}"
    )
    for _, row in curve_events(rows).iterrows():
        click.echo(f"{row['event']} at {first} = {row[first]:.7g}, {second} = {row[second]:.7g}")
    click.echo(f"wrote {output}")
    if plot_path is not None:
        from ..figures.curves import plot_curves

        click.echo(f"plot -> {plot_curves([output, *overlays], plot_path)}")


@main.command("tolerance")
@click.argument("start", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--bifurcation", type=click.IntRange(min=0), default=0, show_default=True,
              help="Which bifurcation of START (an emulated `continue` result), from 0.")  # fmt: skip
@click.option("--delay-from", type=FINITE, default=0.0, show_default=True, help="Shortest transport delay [s].")
@click.option("--delay-to", type=FINITE, default=0.03, show_default=True, help="Longest transport delay [s].")
@click.option(
    "--within",
    type=FINITE,
    default=0.01,
    show_default=True,
    help="Tolerance on the hybrid bifurcation's value relative to the emulated one [-] (0.01: 1 %).",
)
@click.option(
    "--orders",
    default="-1,1,2",
    show_default=True,
    help="Prediction orders to compare, comma-separated (-1: none, 0-4: polynomial order).",
)
@backend_option("the loop's other options (servo, filter, ...), as for sweeps.")
@click.option("--delay-step", type=FINITE, default=2.5e-4, show_default=True,
              help="Spacing of the delay grid [s]; the limit is interpolated on it, and the loop's ripple "
                   "within a tick needs a quarter tick or less.")  # fmt: skip
@click.option("--tol", "newton_tol", type=FINITE, default=1e-9, show_default=True,
              help="Newton tolerance on the scaled update and residual [-].")  # fmt: skip
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Result parquet (default results/tolerance.parquet); each order's grid beside it.")  # fmt: skip
@click.option("--resume", is_flag=True, help="Go on from unfinished curves of the same configuration.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="The delay-tolerance figure (.png/.pdf/.svg).")  # fmt: skip
@_PROGRESS
def tolerance_command(
    start, bifurcation, delay_from, delay_to, within, orders, backend_opts, delay_step, newton_tol,
    output, resume, plot_path, progress,
):  # fmt: skip
    """How far the hybrid test's delay moves a bifurcation of the emulated system, and the largest delay within --within.

    START is an emulated `continue` result; its --bifurcation (e.g. the
    period doubling at 16.097 N) is traced in the hybrid loop (the
    substructured backend, noise off) against its transport delay, for
    each prediction order, by Newton at every delay of a grid. Prints, per
    order, the largest delay (and the total effective delay at the forcing
    frequency) that keeps the bifurcation within --within of the emulated
    value on a stable loop, and where the loop itself loses stability.
    """
    from ..analysis.continuation import ContinuationError
    from ..analysis.continuation.tolerance import ToleranceConfig, run_tolerance

    try:
        order_list = tuple(int(v) for v in orders.split(","))
    except ValueError:
        raise ConfigError(f"--orders {orders!r}: give comma-separated integers from -1 to 4") from None
    config = ToleranceConfig.from_file(
        start,
        bifurcation,
        delays=(delay_from, delay_to),
        within=within,
        orders=order_list,
        backend_options=key_values(backend_opts, "-B"),
        delay_step=delay_step,
        newton_tol=newton_tol,
    )
    output = check_output(output or Path("results/tolerance.parquet"), "-o/--output", (".parquet",))
    check_output(plot_path, "--plot", FIGURE_SUFFIXES)
    progress = sys.stderr.isatty() if progress is None else progress
    try:
        summary = run_tolerance(config, output, progress=progress, resume=resume)
    except ContinuationError as exc:
        raise click.ClickException(str(exc)) from None
    for line in summary["lines"]:
        click.echo(line)
    click.echo(f"wrote {output}")
    if plot_path is not None:
        from ..figures.curves import plot_tolerance

        click.echo(f"plot -> {plot_tolerance(output, plot_path)}")
