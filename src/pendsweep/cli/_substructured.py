"""``pendsweep trace`` and ``pendsweep sync``: hybrid-test time series and their accuracy."""

from __future__ import annotations

from pathlib import Path

import click

from ..errors import ConfigError
from ..model.params import ModelParams
from ._app import ANGLE, FINITE, PATH, RATE, FiniteFloat, LazyChoice, main
from ._checks import (
    FIGURE_SUFFIXES,
    backend_option,
    check_input,
    check_memory,
    check_output,
    key_values,
    model_sets,
    positional_or_output,
)
from ._executor import apply_options, work_options
from ._executor import max_work as work_limit


def _model(alpha, fe, M, C, sets) -> ModelParams:
    changes = model_sets(sets)
    for key, value in (("alpha", alpha), ("fe", fe), ("M", M), ("C", C)):
        if value is not None:
            if key in changes:
                raise ConfigError(f"--{key} {value:g} and --set {key}={changes[key]:g} both fix {key}; give one")
            changes[key] = value
    return ModelParams.from_mapping({"alpha": 5.0, "fe": 2.2} | changes)  # Fig. 9(a) PO unless told


#: Memory per trace row while it is built and written [bytes]: 15 columns of 8 bytes, in the kernel's
#: array, the DataFrame and the Arrow table.
TRACE_BYTES_PER_ROW = 400


@main.command("trace")
@click.argument("positional_output", metavar="[OUTPUT]", type=PATH, required=False)
@click.option("-o", "--output", type=PATH, default=None, help="Trace to write, .parquet (or as OUTPUT).")
@click.option("--alpha", type=FINITE, default=None, help="Forcing amplitude [N] (default 5, Fig. 9 PO).")
@click.option("--fe", type=FINITE, default=None, help="Forcing frequency [Hz] (default 2.2).")
@click.option("--M", "M_", type=FINITE, default=None, help="Oscillator mass M = M1 + M2 [kg] (default 10.9).")
@click.option("--C", "C_", type=FINITE, default=None, help="Oscillator damping C = C1 + C2 [kg/s] (default 20).")
@click.option(
    "--set",
    "sets",
    multiple=True,
    metavar="NAME=VALUE",
    help="Any other model parameter, SI units (e.g. --set M1=10 --set M2=0.9).",
)
@click.option(
    "--backend",
    type=LazyChoice(".backends", "BACKENDS"),
    default="substructured",
    show_default=True,
    help="Simulation backend.",
)
@backend_option("e.g. -B transport_delay=0.02 -B predictor_order=-1 (see docs/substructured.md).")
@click.option(
    "--periods",
    type=click.IntRange(1, 100000),
    default=22,
    show_default=True,
    help="Forcing periods written (22 periods at 2.2 Hz = 10 s).",
)
@click.option(
    "--transient-periods",
    type=click.IntRange(0, 100000),
    default=100,
    show_default=True,
    help="Forcing periods run first and discarded.",
)
@click.option(
    "--stride",
    type=click.IntRange(1, 100000),
    default=1,
    show_default=True,
    help="Write every stride-th controller step.",
)
@click.option(
    "--y0",
    type=FiniteFloat(-10.0, 10.0, "m"),
    default=0.0,
    show_default=True,
    help="Initial displacement [m], within +-10.",
)
@click.option(
    "--theta0", type=ANGLE, default=0.1, show_default=True, help="Initial pendulum angle [rad], within +-10 pi."
)
@click.option(
    "--thetadot0", type=RATE, default=0.0, show_default=True, help="Initial pendulum rate [rad/s], within +-1000."
)
@apply_options(work_options())
def trace_command(
    positional_output, output, alpha, fe, M_, C_, sets, backend, backend_opts, periods, transient_periods, stride, y0, theta0, thetadot0,
    max_work, yes,
):  # fmt: skip
    """Write a time series of one hybrid run to -o FILE (parquet; or OUTPUT, the older positional spelling).

    Substructured columns (SI): t, Fe, y (= y*), ydot, command, x, xdot, x_meas,
    theta (encoder, theta_x), theta_true, thetadot, Fs (load cell), Fs_true,
    F_fb (force fed to the model), sync_error (y* - x_meas).
    """
    from ..backends import make_backend
    from ..engine.scan import Work, check_work
    from ..hybrid.trace import run_trace, write_trace

    output, spelled = positional_or_output(positional_output, output, "OUTPUT")
    check_output(output, spelled, (".parquet",))
    params = _model(alpha, fe, M_, C_, sets)
    b = make_backend(backend, **key_values(backend_opts, "--backend-option"))
    rows = periods * b.steps_per_period(params) / stride
    if not yes:
        check_memory(rows * TRACE_BYTES_PER_ROW, f"a trace of {rows:.3g} rows ({periods} periods, stride {stride})")
    steps = b.steps_per_period(params)
    check_work(Work(1, transient_periods + periods, steps), work_limit(max_work, yes), "trace")
    df = run_trace(b, params, (y0, 0.0, theta0, thetadot0), transient_periods, periods, stride)
    status = df.attrs.get("status", "ok")
    meta = {"params": params.to_dict(), "backend": backend, "backend_options": b.options(),
            "transient_periods": transient_periods, "periods": periods, "stride": stride,
            "initial": [y0, 0.0, theta0, thetadot0], "status": status}  # fmt: skip
    if backend == "substructured":
        meta["effective_delay_s"] = b.effective_delay(params.fe)
        meta["tau_hat_s"] = b.horizon(params) if b.predictor_order >= 0 else None
        meta["filter_delay_s"] = b.filter_delay(params)
    write_trace(df.reset_index(drop=True), output, meta)
    click.echo(f"wrote {len(df)} rows to {output} (status {status})")
    if backend == "substructured" and len(df):
        click.echo(
            f"effective delay {1e3 * meta['effective_delay_s']:.2f} ms at {params.fe:g} Hz; "
            f"sync ratio max|y*-x|/max|y*| = {100 * df['sync_error'].abs().max() / df['y'].abs().max():.2f} %"
        )


@main.command("sync")
@click.argument("trace", type=PATH)
@click.option(
    "-o",
    "--output",
    type=PATH,
    default=None,
    help="Figure file, .png/.pdf/.svg (default: TRACE with .png).",
)
@click.option(
    "--reference", type=LazyChoice(".hybrid.sync", "TABLE_I"), default=None, help="Also print the paper's Table I row."
)
@click.option(
    "--window",
    type=click.FloatRange(0.01, 1e4),
    default=1.0,
    show_default=True,
    help="Sliding window of the online delay estimate [s].",
)
@click.option(
    "--session",
    type=click.IntRange(0, 10**6),
    default=None,
    help="With a site log: the client session to analyse (default: the last).",
)
def sync_command(trace, output, reference, window, session):
    """Synchronisation accuracy of a substructured TRACE (Table I, J1-J3, Fig. 12 panels).

    TRACE is a `pendsweep trace` file or a `pendsweep site` log (target: the
    command d; achieved: the LVDT reading x_meas).

    Prints the metrics, draws subspace, error, error PSD and the online delay
    estimate, and writes the estimate's time series next to the figure.
    """
    from ..figures.hybrid import draw_sync
    from ..hybrid.sync import analyse
    from ..hybrid.trace import read_trace

    check_input(trace, "trace")
    path = check_output(output or Path(trace).with_suffix(".png"), "-o/--output", FIGURE_SUFFIXES)
    check_output(path.with_name(path.stem + "_delay.csv"), "-o/--output (its _delay.csv)")
    try:
        df, meta = read_trace(trace, session)
    except ValueError as exc:  # metadata that is not JSON
        raise ConfigError(f"TRACE {str(trace)!r}: its pendsweep metadata is not valid JSON ({exc})") from None
    if meta.get("backend") != "substructured":
        raise ConfigError(
            f"{str(trace)!r} was written by backend {meta.get('backend')!r}; sync needs a substructured trace"
        )
    report = analyse(df, window)
    for line in report.lines(reference):
        click.echo(line)
    draw_sync(df, report, path)
    delay_csv = path.with_name(path.stem + "_delay.csv")
    report.delay_online.to_csv(delay_csv, index=False)
    click.echo(f"wrote {path} and {delay_csv} (online delay estimate: t [s], delay [s])")
