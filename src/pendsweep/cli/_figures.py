"""Drawing and listing commands: ``plot``, ``figures``, ``params``."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import ConfigError
from ..model.params import PARAM_SPECS, ModelParams
from ._app import PATH, main
from ._checks import FIGURE_SUFFIXES, check_input, check_output, check_output_dir
from ._sweep import read_sweep_metadata


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
    from ..figures.overlay import plot_any

    for path in results:
        if path.suffix == ".json":
            check_continuation_document(path)
        else:
            read_sweep_metadata(path)
    output = check_output(output or Path(results[0]).with_suffix(".png"), "-o/--output", FIGURE_SUFFIXES)
    click.echo(f"plot -> {plot_any(list(results), output, observable, title)}")


def check_continuation_document(path: Path) -> None:
    """Refuse a ``.json`` that is not a readable continuation result, naming it."""
    from ..analysis.continuation.run import read_json

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
            from ..measured.records import DATA_ENV

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
