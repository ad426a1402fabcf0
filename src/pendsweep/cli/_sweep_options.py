"""The sweep commands' options, and the configuration a sweep is built from them."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import click

from ..errors import ConfigError
from ..model.params import ModelParams
from ..studies.sweepfile import MAX_POINTS, MAX_STARTS, describe_count, grid_size
from ._app import ANGLE, FINITE, PATH, PERIODS, RATE, SEED, SMALL_ANGLE, STEP_S, LazyChoice, given
from ._checks import check_input, key_values, model_sets
from ._executor import checkpoint_option, executor_options, work_options


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
    type=LazyChoice(".backends.gpu", "DEVICES"),
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
                type=LazyChoice(".studies.sweep", "MODES"),
                default="continue",
                show_default=True,
                help="continue: carry the state (kick 0.1 rad when at rest); fresh: same start every point; multistart: --starts seeded starts per point.",
            ),
            click.option(
                "--direction",
                type=LazyChoice(".studies.sweep", "DIRECTIONS"),
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
                type=LazyChoice(".studies.sweep", "TRANSIENTS"),
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
                "--ramp",
                "ramp_periods",
                type=click.IntRange(0, PERIODS.max),
                default=0,
                show_default=True,
                help="Continue mode: move the parameter linearly over this many forcing periods at the start of "
                "each point's transient instead of stepping it (0: the paper's step).",
            ),
            click.option(
                "--stop-periods",
                type=click.IntRange(1, 1000),
                default=5,
                show_default=True,
                help="A remote rig's continuous test: forcing periods over which a safe stop (a signal, a limit, "
                "an unstable loop) ramps the forcing to zero before die.",
            ),
            click.option(
                "--rest-threshold",
                type=SMALL_ANGLE,
                default=0.0013,
                show_default=True,
                help="At rest: max|theta| below this [rad] (one encoder pulse), 0 to pi.",
            ),
            click.option(
                "--evidence",
                type=LazyChoice(".analysis.classify", "EVIDENCE_MODES"),
                default="staged",
                show_default=True,
                help="What the motion classifier simulates past an undecided record: staged (an extension that "
                "stops once the section repeats, the Lyapunov pair only where needed) or full (200 periods and the "
                "pair for every such point).",
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
    for name, flag in (("direction", "direction"), ("kick", "kick"), ("ramp_periods", "ramp")):
        if mode != "continue" and given(ctx, name):
            raise ConfigError(f"--{flag} {kw[name]} applies only to --mode continue (mode is {mode})")
    if kw["transient"] == "auto" and given(ctx, "transient_periods"):
        raise ConfigError(f"--transient-periods {kw['transient_periods']} applies only to --transient fixed")
    if kw["transient"] == "fixed" and given(ctx, "max_transient_periods"):
        raise ConfigError(f"--max-transient-periods {kw['max_transient_periods']} applies only to --transient auto")


def build_config(parameter: str, default_step: float, kw: dict[str, Any], ctx: click.Context | None = None):
    """SweepConfig from the shared sweep options (every check that needs no simulation runs here)."""
    from ..studies.sweep import SweepConfig, value_range

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
    from ..backends.gpu import with_device

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
        kick=_kick(kw, backend_options, ctx),
        rest_threshold=kw["rest_threshold"],
        evidence=kw["evidence"],
        starts=kw["starts"] if kw["mode"] == "multistart" else 1,
        seed=kw["seed"],
        transient=kw["transient"],
        max_transient_periods=kw["max_transient_periods"],
        ramp_periods=kw["ramp_periods"],
    )


def _kick(kw: dict[str, Any], backend_options: dict[str, Any], ctx: click.Context | None) -> float:
    """The kick [rad]: 0 on a remote rig unless given (its pendulum cannot be kicked from the client; then refused)."""
    if backend_options.get("rig") and kw["mode"] == "continue" and not (ctx is not None and given(ctx, "kick")):
        return 0.0
    return kw["kick"]
