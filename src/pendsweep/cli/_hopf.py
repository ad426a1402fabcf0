"""``pendsweep hopf``: Hopf-boundary scans over (omega_hat, M, method)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ..backends import BACKENDS
from ..errors import ConfigError
from ..executors import make_executor
from ..hopf import METHODS, HopfConfig, run_hopf
from ..params import ENCODER_RESOLUTION
from ..sweep import value_range
from ._app import FINITE, main
from ..gpu import with_device
from ._executor import apply_options, executor_options, work_options
from ._sweep import DEVICE_OPTION, _finite, _key_value


def parse_values(text: str, what: str) -> tuple[float, ...]:
    """``FROM:TO:N`` (N points, ends included), ``A,B,C`` or a single value."""
    try:
        if ":" in text:
            start, stop, count = text.split(":")
            if int(count) != float(count):
                raise ValueError
            return tuple(float(v) for v in value_range(float(start), float(stop), points=int(count)))
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(
            f"{what} = {text!r}: give FROM:TO:N (N points), a comma list A,B,C or a single number"
        ) from None


@main.command()
@click.option("--what", "what", required=True, metavar="RANGE",
              help="omega_hat = w_e/(2 w_p) [-]: FROM:TO:N (N points), A,B,C, or one value (e.g. 1.1087 is fe = 2.5 Hz).")
@click.option("--M", "masses", default="10.9", show_default=True, metavar="LIST",
              help="Oscillator masses M [kg], comma separated.")
@click.option("--method", "methods", default=",".join(METHODS), show_default=True, metavar="LIST",
              help="Methods, comma separated: analytic (Eq. 12), floquet (Mathieu monodromy), simulate (kick + bisection).")
@click.option("--backend", type=click.Choice(sorted(BACKENDS)), default="emulated", show_default=True,
              help="Backend of the simulate method.")
@click.option("-B", "--backend-option", "backend_options", multiple=True, metavar="KEY=VALUE",
              help="Backend option (repeatable), e.g. dt=0.001 [s].")
@DEVICE_OPTION
@click.option("--set", "model", multiple=True, metavar="NAME=VALUE",
              help="Model parameter override in SI units (repeatable), e.g. --set b1=0 --set C=20.")
@click.option("--kick", type=FINITE, default=0.01, show_default=True, help="Simulate: pendulum kick [rad].")
@click.option("--periods", type=click.IntRange(min=2), default=200, show_default=True,
              help="Simulate: forcing periods recorded after the kick [-].")
@click.option("--tol", type=FINITE, default=0.1, show_default=True, help="Simulate: bisection bracket width [N].")
@click.option("--alpha-max", type=FINITE, default=500.0, show_default=True,
              help="Largest forcing amplitude searched [N].")
@click.option("--rest-threshold", type=FINITE, default=ENCODER_RESOLUTION, show_default=True,
              help="Simulate: the kicked pendulum is at rest when its last period's max|theta| is below this [rad].")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              default=Path("results/hopf.parquet"), show_default=True, help="Results parquet file (resumable).")
@click.option("-j", "--jobs", type=int, default=-1, show_default=True, help="Parallel workers (-1: all cores).")
@click.option("--overwrite", is_flag=True, help="Discard earlier results at --output instead of resuming.")
@click.option("--progress/--no-progress", default=None, help="Progress bar on stderr (default: when stderr is a terminal).")
@apply_options(executor_options() + work_options())
def hopf(what, masses, methods, backend, backend_options, device, model, kick, periods, tol, alpha_max,
         rest_threshold, output, jobs, overwrite, progress, executor, scheduler, max_work, yes):
    """Hopf boundary alpha_H [N] of the semi-trivial solution (Fig. 10).

    Writes one row per (omega_hat, M, method) with alpha_H and diagnostics
    (critical Floquet multiplier, envelope growth rates [1/period] at the
    final bisection bracket, kick [rad], runs) and prints the table.
    Rerunning the same command resumes an interrupted scan.
    """
    options = _key_value(backend_options, "--backend-option")
    config = HopfConfig(
        omega_hat=parse_values(what, "--what"),
        masses=parse_values(masses, "--M"),
        methods=tuple(m.strip() for m in methods.split(",") if m.strip()),
        model={k: _finite(k, v) for k, v in _key_value(model, "--set").items()},
        backend=backend,
        backend_options=with_device(backend, options, device or options.get("device")),
        kick=kick, periods=periods, tol=tol, alpha_max=alpha_max, rest_threshold=rest_threshold,
    )
    progress = sys.stderr.isatty() if progress is None else progress
    runner = make_executor(executor, scheduler)
    try:
        df = run_hopf(config, output, n_jobs=jobs, progress=progress, overwrite=overwrite, executor=runner,
                      max_work=None if yes else max_work)
    finally:
        runner.close()
    shown = ["omega_hat", "fe", "M", "method", "alpha_H", "status", "multiplier", "growth_above", "kick", "runs"]
    click.echo(df[shown].to_string(index=False, float_format=lambda v: f"{v:.5g}"))
    click.echo(f"wrote {output}", err=True)

