"""``pendsweep hopf``: Hopf-boundary scans over (omega_hat, M, method)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import click

from ..errors import ConfigError
from ..model.params import ENCODER_RESOLUTION
from ..studies.sweepfile import MAX_POINTS
from ._app import PATH, SMALL_ANGLE, FiniteFloat, LazyChoice, main
from ._checks import check_output, key_values, model_sets
from ._executor import apply_options, checkpoint_option, executor_options, work_options
from ._sweep import prepare_output
from ._sweep_options import DEVICE_OPTION

#: Model parameters the scan itself sets: alpha is searched, fe follows --what, M is --M.
SCANNED = {"alpha": "the searched amplitude", "fe": "set by --what (fe = omega_hat w_p / pi)", "M": "set by --M"}
DEFAULT_OUTPUT = Path("results/hopf.parquet")


def parse_values(text: str, what: str) -> tuple[float, ...]:
    """``FROM:TO:N`` (N points, ends included), ``A,B,C`` or a single value."""
    from ..studies.sweep import value_range

    accepted = "give FROM:TO:N (N points), a comma list A,B,C or a single number"
    try:
        if ":" in text:
            start, stop, count = text.split(":")
            bounds, n = (float(start), float(stop)), int(count)
        else:
            return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(f"{what} = {text!r}: {accepted}") from None
    if not 1 <= n <= MAX_POINTS:
        raise ConfigError(f"{what} = {text!r}: N = {n} must be between 1 and {MAX_POINTS}")
    return tuple(value_range(*bounds, points=n).tolist())


#: Rows printed at most; a longer scan prints rows evenly spaced through it (the file holds all).
MAX_ROWS_SHOWN = 60


def _all_methods() -> str:
    from ..studies.hopf import METHODS

    return ",".join(METHODS)


@main.command()
@click.option(
    "--what",
    "what",
    required=True,
    metavar="RANGE",
    help="omega_hat = w_e/(2 w_p) [-]: FROM:TO:N (N points), A,B,C, or one value (e.g. 1.1087 is fe = 2.5 Hz).",
)
@click.option(
    "--M",
    "masses",
    default="10.9",
    show_default=True,
    metavar="LIST",
    help="Oscillator masses M [kg], comma separated.",
)
@click.option(
    "--method",
    "methods",
    default=_all_methods,
    show_default="analytic,floquet,simulate",
    metavar="LIST",
    help="Methods, comma separated: analytic (Eq. 12), floquet (Mathieu monodromy), simulate (kick + bisection).",
)
@click.option(
    "--backend",
    type=LazyChoice(".backends", "BACKENDS"),
    default="emulated",
    show_default=True,
    help="Backend of the simulate method.",
)
@click.option(
    "-B",
    "--backend-option",
    "backend_options",
    multiple=True,
    metavar="KEY=VALUE",
    help="Backend option (repeatable), e.g. dt=0.001 [s].",
)
@DEVICE_OPTION
@click.option(
    "--set",
    "model",
    multiple=True,
    metavar="NAME=VALUE",
    help="Model parameter override in SI units (repeatable), e.g. --set b1=0 --set C=20.",
)
@click.option(
    "--kick",
    type=FiniteFloat(1e-9, math.pi, "rad"),
    default=0.01,
    show_default=True,
    help="Simulate: pendulum kick [rad], 1e-9 to pi.",
)
@click.option(
    "--periods",
    type=click.IntRange(2, 1_000_000),
    default=200,
    show_default=True,
    help="Simulate: forcing periods recorded after the kick [-].",
)
@click.option(
    "--tol",
    type=FiniteFloat(1e-9, 1e6, "N"),
    default=0.1,
    show_default=True,
    help="Simulate: bisection bracket width [N], 1e-9 to 1e6.",
)
@click.option(
    "--alpha-max",
    type=FiniteFloat(1e-9, 1e9, "N"),
    default=500.0,
    show_default=True,
    help="Largest forcing amplitude searched [N].",
)
@click.option(
    "-o",
    "--output",
    type=PATH,
    default=None,
    help="Results file, .parquet (resumable; default results/hopf.parquet, replaced when it holds another scan).",
)
@click.option("-j", "--jobs", type=int, default=-1, show_default=True, help="Parallel workers (-1: all cores).")
@click.option("--overwrite", is_flag=True, help="Discard earlier results at --output instead of resuming.")
@checkpoint_option()
@click.option(
    "--progress/--no-progress", default=None, help="Progress bar on stderr (default: when stderr is a terminal)."
)
@click.option(
    "--rest-threshold",
    type=SMALL_ANGLE,
    default=ENCODER_RESOLUTION,
    show_default=True,
    help="Simulate: the kicked pendulum is at rest when its last period's max|theta| is below this [rad], 0 to pi.",
)
@apply_options(executor_options() + work_options())
def hopf(
    what,
    masses,
    methods,
    backend,
    backend_options,
    device,
    model,
    kick,
    periods,
    tol,
    alpha_max,
    rest_threshold,
    output,
    jobs,
    overwrite,
    checkpoint_seconds,
    progress,
    executor,
    scheduler,
    max_work,
    yes,
):
    """Hopf boundary alpha_H [N] of the semi-trivial solution (Fig. 10).

    Writes one row per (omega_hat, M, method) with alpha_H and diagnostics
    (critical Floquet multiplier, envelope growth rates [1/period] at the
    final bisection bracket, kick [rad], runs) and prints the table.
    Rerunning the same command resumes an interrupted scan.
    """
    from ..backends.gpu import with_device
    from ..engine.executors import make_executor
    from ..studies.hopf import HopfConfig, hopf_metadata, run_hopf

    check_output(output, "-o/--output", (".parquet",))
    fixed = model_sets(model)
    for name, why in SCANNED.items():
        if name in fixed:
            raise ConfigError(f"--set {name}={fixed[name]:g} is ignored by a Hopf scan ({name} is {why}); drop it")
    options = key_values(backend_options, "--backend-option")
    config = HopfConfig(
        omega_hat=parse_values(what, "--what"),
        masses=parse_values(masses, "--M"),
        methods=tuple(m.strip() for m in methods.split(",") if m.strip()),
        model=fixed,
        backend=backend,
        backend_options=with_device(backend, options, device or options.get("device")),
        kick=kick, periods=periods, tol=tol, alpha_max=alpha_max, rest_threshold=rest_threshold,
    )  # fmt: skip
    default = output is None
    output = DEFAULT_OUTPUT if default else output
    overwrite = prepare_output(output, hopf_metadata(config)["config_hash"], default=default, overwrite=overwrite)
    progress = sys.stderr.isatty() if progress is None else progress
    runner = make_executor(executor, scheduler)
    try:
        df = run_hopf(
            config,
            output,
            n_jobs=jobs,
            progress=progress,
            overwrite=overwrite,
            executor=runner,
            max_work=None if yes else max_work,
            checkpoint_seconds=checkpoint_seconds,
        )
    finally:
        runner.close()
    shown = ["omega_hat", "fe", "M", "method", "alpha_H", "status", "multiplier", "growth_above", "kick", "runs"]
    table = df[shown]
    if len(df) > MAX_ROWS_SHOWN:
        table = table.iloc[[round(k * (len(df) - 1) / (MAX_ROWS_SHOWN - 1)) for k in range(MAX_ROWS_SHOWN)]]
    click.echo(table.to_string(index=False, float_format=lambda v: f"{v:.5g}"))
    if len(df) > MAX_ROWS_SHOWN:
        click.echo(f"({MAX_ROWS_SHOWN} of {len(df)} rows shown, evenly spaced; all in {output})")
    click.echo(f"wrote {output}", err=True)
