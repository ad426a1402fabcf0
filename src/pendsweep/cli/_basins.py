"""Global-dynamics commands: ``basins`` (basins of attraction, fractions against a parameter) and ``map``."""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import click

from ..engine.scan import per_start_max_work
from ..errors import ConfigError, ParameterError
from ..model.params import PARAM_SPECS
from ._app import ANGLE, FINITE, RATE, SEED, LazyChoice, main
from ._checks import FIGURE_SUFFIXES, backend_option, check_output, key_values
from ._executor import apply_options, checkpoint_option, executor_options, max_work, work_options
from ._sweep_options import DEVICE_OPTION, load_model_file

#: Columns of a map's rows that its counts and image need (read back from the file, not held by the run).
MAP_SUMMARY_COLUMNS = ["ix", "iy", "motion", "theta_absmax"]
_MODEL_FLAGS = (("alpha", "alpha", "N"), ("fe", "fe", "Hz"), ("M", "M_", "kg"), ("C", "C_", "kg/s"), ("K", "K_", "N/m"))


def _finite(name: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ParameterError(f"{name} = {text!r} is not a number") from None
    if not math.isfinite(value):
        raise ParameterError(f"{name} = {text!r} is not finite; give a finite number")
    return value


def _model_options(axis_values: bool):
    """--alpha/--fe/--M/--C/--K, --set, --model; with ``axis_values`` each may also be FROM:TO:N."""
    kind = str if axis_values else FINITE
    extra = " or FROM:TO:N for a map axis" if axis_values else ""
    return [
        *(
            click.option(
                f"--{name}",
                key,
                type=kind,
                default=None,
                help=f"{name} [{unit}]{extra} (default: Table IV / Fig. 11 model).",
            )
            for name, key, unit in _MODEL_FLAGS
        ),
        click.option(
            "--set",
            "sets",
            multiple=True,
            metavar="NAME=VALUE",
            help="Any other model parameter, SI units (see `pendsweep params`)"
            + (", or NAME=FROM:TO:N." if axis_values else "."),
        ),
        click.option(
            "--model",
            "model_file",
            type=click.Path(dir_okay=False, path_type=Path),
            default=None,
            help="JSON file of model parameters (e.g. from `pendsweep diagnose`).",
        ),
    ]


def _model(kw: dict[str, Any]) -> dict[str, Any]:
    """Model overrides from --model, the flags and --set (values as given: numbers or axis strings)."""
    model: dict[str, Any] = {}
    if kw["model_file"] is not None:
        model.update(load_model_file(kw["model_file"]))
    for name, key, _ in _MODEL_FLAGS:
        if kw[key] is not None:
            model[name] = kw[key]
    model.update(key_values(kw["sets"], "--set"))
    for name in model:
        if name not in PARAM_SPECS:
            raise ParameterError(f"unknown parameter {name!r}; known: {', '.join(PARAM_SPECS)}")
    return model


def _interval(text: str | None, name: str, unit: str) -> tuple[float, float] | None:
    if text is None:
        return None
    parts = text.split(":")
    try:
        a, b = (float(p) for p in parts)
    except ValueError:
        raise ConfigError(f"--{name} {text!r}: give A:B in {unit}, A < B") from None
    if not (math.isfinite(a) and math.isfinite(b) and a < b):
        raise ConfigError(f"--{name} {text!r}: give finite A < B in {unit}")
    return a, b


def _grid(text: str) -> tuple[int, int]:
    try:
        a, b = (int(p) for p in text.lower().split("x"))
    except ValueError:
        raise ConfigError(f"--grid {text!r}: give NTHETAxNTHETADOT, e.g. 200x200 (each >= 1)") from None
    if a < 1 or b < 1:
        raise ConfigError(f"--grid {text!r}: both counts must be >= 1")
    return a, b


def _progress(flag: bool | None) -> bool:
    return sys.stderr.isatty() if flag is None else flag


@main.command("basins")
@click.argument("parameter", required=False)
@click.option("--from", "start", type=FINITE, default=None, help="First value of PARAMETER (its units).")
@click.option("--to", "stop", type=FINITE, default=None, help="Last value of PARAMETER, included when on the grid.")
@click.option("--step", type=FINITE, default=None, help="Increment of PARAMETER.")
@click.option("--points", type=int, default=None, help="Number of PARAMETER values instead of --step.")
@apply_options(_model_options(False))
@click.option(
    "--grid",
    "grid",
    default=None,
    metavar="NxM",
    help="Grid of N theta x M thetadot starts (cell centres) instead of random samples.",
)
@click.option(
    "--starts",
    "--samples",
    "samples",
    type=int,
    default=1000,
    show_default=True,
    help="Random starts per point (as the sweeps' multistart --starts; --samples is its old name).",
)
@click.option(
    "--seed",
    type=SEED,
    default=0,
    show_default=True,
    help="Seed of the random starts and of backend noise (0 to 2**63-1).",
)
@click.option(
    "--theta", "theta_range", default=None, metavar="A:B", help="Initial theta interval [rad] (default -pi:pi)."
)
@click.option(
    "--thetadot",
    "thetadot_range",
    default=None,
    metavar="A:B",
    help="Initial thetadot interval [rad/s] (default +-omega_p).",
)
@click.option(
    "--max-periods",
    type=int,
    default=1000,
    show_default=True,
    help="Forcing periods after which a start counts as unsettled.",
)
@click.option(
    "--round-periods", type=int, default=25, show_default=True, help="Forcing periods between settling checks."
)
@click.option(
    "--tol",
    type=FINITE,
    default=None,
    help="Settling tolerance on the normalised section [~rad] (default 1e-3 emulated, 0.01 other backends).",
)
@click.option(
    "--backend",
    type=LazyChoice(".backends", "BACKENDS"),
    default="emulated",
    show_default=True,
    help="Simulation backend (substructured: with its noise, one start at a time).",
)
@backend_option("e.g. -B force_noise=0.3.")
@click.option("--dt", type=FINITE, default=None, help="Integration / controller step [s] (default 0.001).")
@DEVICE_OPTION
@click.option(
    "-j",
    "--jobs",
    type=int,
    default=-1,
    show_default=True,
    help="Threads for one-start-at-a-time backends (-1: all cores).",
)
@apply_options(
    executor_options()
    + work_options(None, "1e13 (a day of the batched kernel), 1e11 one start at a time (the substructured loop)")
)
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path),
    default=Path("results/basins.parquet"),
    show_default=True,
    help="Per-start results parquet (resumable).",
)
@click.option(
    "--json",
    "json_path",
    type=click.Path(path_type=Path),
    default=None,
    help="Write the summary (fractions, stderr, settling times, escape rate, attractors) here.",
)
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(path_type=Path),
    default=None,
    help="Basin map and survival curves (one value) or stacked fractions (a range).",
)
@click.option("--overwrite", is_flag=True, help="Replace earlier results at --output instead of resuming.")
@checkpoint_option()
@click.option(
    "--progress/--no-progress", default=None, help="Progress bar on stderr (default: when stderr is a terminal)."
)
def basins_command(parameter, start, stop, step, points, **kw):
    """Basins of attraction of the settled motions, at one parameter point or along PARAMETER.

    Starts have y = ydot = 0 and (theta, thetadot) drawn like multistart
    sweeps (or on --grid). Each start runs until its stroboscopic section
    repeats (periodic-n, n <= 8, or a rotation) to 1e-3, or --max-periods.

    \b
    Examples:
      pendsweep basins --alpha 40 --fe 2.5 --grid 200x200 --max-periods 1000 -o b.parquet --json b.json --plot b.png
      pendsweep basins alpha --from 30 --to 45 --step 0.5 --samples 500 --plot fractions.png
    """
    from ..backends.gpu import with_device
    from ..engine.executors import make_executor
    from ..figures.basins import plot_basin, plot_scan
    from ..studies.basins import BasinConfig, run_basins, scan_summary
    from ..studies.sweep import value_range

    check_output(kw["output"], "-o/--output", (".parquet",))
    check_output(kw["json_path"], "--json", (".json",))
    check_output(kw["plot_path"], "--plot", FIGURE_SUFFIXES)
    model = {k: _finite(k, v) if isinstance(v, str) else v for k, v in _model(kw).items()}
    if parameter is None:
        if any(v is not None for v in (start, stop, step, points)):
            raise ConfigError(
                "--from/--to/--step/--points need a PARAMETER, e.g. `pendsweep basins alpha --from 30 --to 45`"
            )
        parameter = "alpha"
        values = (model.pop("alpha", 17.0),)
    else:
        if parameter not in PARAM_SPECS:
            raise ParameterError(f"unknown parameter {parameter!r}; known: {', '.join(PARAM_SPECS)}")
        if start is None or stop is None:
            raise ConfigError(f"basins {parameter} needs --from and --to")
        if step is None and points is None:
            raise ConfigError("give --step or --points for the parameter range")
        values = tuple(value_range(start, stop, step, points))
        if parameter in model:
            raise ConfigError(f"{parameter} is the stepped PARAMETER; drop its fixed value {model[parameter]!r}")
    backend_options = key_values(kw["backend_opts"], "--backend-option")
    if kw["dt"] is not None:
        backend_options["dt"] = kw["dt"]
    backend_options = with_device(kw["backend"], backend_options, kw["device"] or backend_options.get("device"))
    config = BasinConfig(
        parameter=parameter,
        values=values,
        model=model,
        sampling="grid" if kw["grid"] else "random",
        samples=kw["samples"],
        grid=_grid(kw["grid"]) if kw["grid"] else (1, 1),
        seed=kw["seed"],
        theta_range=_interval(kw["theta_range"], "theta", "rad") or (-math.pi, math.pi),
        thetadot_range=_interval(kw["thetadot_range"], "thetadot", "rad/s"),
        max_periods=kw["max_periods"],
        round_periods=kw["round_periods"],
        tol=kw["tol"],
        backend=kw["backend"],
        backend_options=backend_options,
    )
    output = kw["output"]
    if output.exists() and not kw["overwrite"]:
        click.echo(f"{output} exists: reusing it if its configuration matches (--overwrite recomputes)")
    t0 = time.perf_counter()
    runner = make_executor(kw["executor"], kw["scheduler"])
    try:
        df = run_basins(
            config,
            output,
            n_jobs=kw["jobs"],
            progress=_progress(kw["progress"]),
            overwrite=kw["overwrite"],
            executor=runner,
            checkpoint_seconds=kw["checkpoint_seconds"],
            max_work=max_work(kw["max_work"] or per_start_max_work(kw.get("backend", "emulated")), kw["yes"]),
        )
    finally:
        runner.close()
    elapsed = time.perf_counter() - t0
    summary, rows = scan_summary(config, df)
    _rewrite_with_attractors(output, rows)
    click.echo(f"{len(df)} starts at {len(values)} value(s) of {parameter} in {elapsed:.1f} s -> {output}")
    if len(values) == 1:
        fr = ", ".join(
            f"{k} {100 * v:.1f} ± {100 * summary['stderr'][k]:.1f}%" for k, v in summary["fractions"].items()
        )
        click.echo(f"fractions: {fr}")
        sp = summary["settling_periods"]
        click.echo(
            f"settling periods: median {sp['median']}, q90 {sp['q90']}; escape rate "
            + (f"{summary['escape_rate']:.4f} per period" if summary["escape_rate"] else "none (no exponential tail)")
        )
        for a in summary["attractors"]:
            click.echo(
                f"  attractor {a['id']}: {a['motion']} "
                # period 0: settled by a steady rotation number, its section never repeating (quasi-periodic)
                + (f"period {a['period']}" if a["period"] else "no section period")
                + f" rotation {a['rotation_number']:+g} "
                f"max|theta| {a['theta_absmax']:.3f} rad: {100 * a['fraction']:.2f} ± {100 * a['stderr']:.2f}%"
            )
    else:
        for v, u in zip(summary["values"], summary["unsettled_after_100"]):
            parts = ", ".join(
                f"{c} {100 * summary['classes'][c][summary['values'].index(v)]:.0f}%" for c in summary["classes"]
            )
            late = f"{100 * u:.0f}%" if u == u else "not known (runs stop at --max-periods)"
            click.echo(f"  {parameter} = {v:g}: {parts}; unsettled after 100 periods {late}")
    if kw["json_path"] is not None:
        kw["json_path"].parent.mkdir(parents=True, exist_ok=True)
        kw["json_path"].write_text(json.dumps(summary, indent=1, default=_json_default))
        click.echo(f"summary -> {kw['json_path']}")
    if kw["plot_path"] is not None:
        kw["plot_path"].parent.mkdir(parents=True, exist_ok=True)
        path = (
            plot_basin(rows, summary, config, kw["plot_path"])
            if len(values) == 1
            else plot_scan(summary, kw["plot_path"])
        )
        click.echo(f"plot -> {path}")


def _json_default(value):
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def _rewrite_with_attractors(output: Path, rows) -> None:
    """Add the attractor id column to the finished results file (same metadata, atomic)."""
    from ..engine.results import atomic_write_table, read_metadata, with_metadata

    if "attractor" in read_metadata(output).get("columns_added", []):
        return
    import pyarrow.parquet as pq

    table = pq.read_table(output).to_pandas()
    table = table.sort_values(["point", "start"], kind="stable").reset_index(drop=True)
    table["attractor"] = rows.sort_values(["point", "start"], kind="stable")["attractor"].to_numpy()
    meta = dict(read_metadata(output), columns_added=["attractor"])
    atomic_write_table(with_metadata(table, meta), output)


@main.command("map")
@click.argument("x")
@click.argument("y")
@apply_options(_model_options(True))
@click.option(
    "--theta0",
    type=ANGLE,
    default=0.1,
    show_default=True,
    help="Initial pendulum angle of every cell [rad], within +-10 pi.",
)
@click.option(
    "--thetadot0",
    type=RATE,
    default=0.0,
    show_default=True,
    help="Initial pendulum rate of every cell [rad/s], within +-1000.",
)
@click.option(
    "--max-periods",
    type=int,
    default=300,
    show_default=True,
    help="Forcing periods after which a cell counts as unsettled.",
)
@click.option("--dt", type=FINITE, default=1e-3, show_default=True, help="Requested RK4 step [s].")
@DEVICE_OPTION
@apply_options(
    executor_options()
    + work_options(None, "1e13 (a day of the batched kernel), 1e11 one start at a time (the substructured loop)")
)
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path),
    default=Path("results/map.parquet"),
    show_default=True,
    help="Per-cell results parquet (resumable).",
)
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(path_type=Path),
    default=None,
    help="Image of the motion class and max|theta| with the Hopf boundaries.",
)
@click.option("--overwrite", is_flag=True, help="Replace earlier results at --output instead of resuming.")
@checkpoint_option()
@click.option(
    "--progress/--no-progress", default=None, help="Progress bar on stderr (default: when stderr is a terminal)."
)
def map_command(x, y, **kw):
    """Motion class and settled max|theta| over a grid of two model parameters X and Y.

    Give each axis as FROM:TO:N through its flag (--alpha, --fe, --M, --C,
    --K) or --set NAME=FROM:TO:N. When one axis is alpha, the Eq. (12) and
    Floquet Hopf boundaries are drawn over the image.

    \b
    Example: pendsweep map alpha fe --alpha 0:45:200 --fe 2.0:3.0:200 --plot map.png
    """
    import pyarrow.parquet as pq

    from ..backends.gpu import require_cuda
    from ..engine.executors import make_executor
    from ..figures.basins import plot_map
    from ..studies.maps import MapConfig, hopf_boundaries, parse_axis, run_map

    check_output(kw["output"], "-o/--output", (".parquet",))
    check_output(kw["plot_path"], "--plot", FIGURE_SUFFIXES)
    raw = _model(kw)
    if x == y:
        raise ConfigError(f"the two map axes must differ (both are {x!r})")
    axes = {}
    for name in (x, y):
        if name not in PARAM_SPECS:
            raise ParameterError(f"unknown parameter {name!r}; known: {', '.join(PARAM_SPECS)}")
        if name not in raw:
            raise ConfigError(f"give the {name} axis as --{name} FROM:TO:N (or --set {name}=FROM:TO:N)")
        axes[name] = parse_axis(raw.pop(name), name)
    model = {k: _finite(k, v) if isinstance(v, str) else v for k, v in raw.items()}
    device = kw["device"] or "cpu"
    if device == "cuda":
        require_cuda()  # before any work
    config = MapConfig(
        x, axes[x], y, axes[y], model, (kw["theta0"], kw["thetadot0"]), kw["max_periods"], dt=kw["dt"], device=device
    )
    output = kw["output"]
    t0 = time.perf_counter()
    runner = make_executor(kw["executor"], kw["scheduler"])
    try:
        run_map(
            config,
            output,
            progress=_progress(kw["progress"]),
            overwrite=kw["overwrite"],
            executor=runner,
            checkpoint_seconds=kw["checkpoint_seconds"],
            max_work=max_work(kw["max_work"] or per_start_max_work(kw.get("backend", "emulated")), kw["yes"]),
            return_rows=False,
        )
    finally:
        runner.close()
    # The counts and the image need four columns: a 1000 x 1000 map never holds the other twenty.
    df = pq.read_table(output, columns=MAP_SUMMARY_COLUMNS).to_pandas()
    counts = ", ".join(f"{n} {m}" for m, n in df["motion"].value_counts().items())
    click.echo(f"{len(df)} cells ({counts}) in {time.perf_counter() - t0:.1f} s -> {output}")
    if kw["plot_path"] is not None:
        kw["plot_path"].parent.mkdir(parents=True, exist_ok=True)
        click.echo(f"plot -> {plot_map(df, config, hopf_boundaries(config), kw['plot_path'])}")
