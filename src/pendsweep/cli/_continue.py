"""``pendsweep continue``: periodic orbits by shooting and pseudo-arclength continuation."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ..errors import ConfigError
from ._app import FINITE, LazyChoice, main
from ._checks import FIGURE_SUFFIXES, backend_option, check_output, key_values, model_sets
from ._executor import apply_options, work_options
from ._executor import max_work as work_limit
from ._sweep import read_sweep_metadata
from ._sweep_options import load_model_file


def _aliases(parameter: str) -> set[str]:
    """Names that set the continued ``parameter`` (M1/C1 set M/C)."""
    return {parameter, f"{parameter}1"} if parameter in ("M", "C") else {parameter}


def _deprecated_json(value: Path | None) -> Path | None:
    """``--json FILE``, the old name of ``-o/--output``: still accepted, with a warning naming both."""
    if value is not None:
        click.echo("Warning: --json is deprecated; use -o/--output", err=True)
    return value


@main.command("continue")
@click.argument("parameter", type=LazyChoice(".analysis.continuation.run", "CONTINUABLE"))
@click.option(
    "--from",
    "start",
    type=FINITE,
    required=True,
    help="Start of the parameter interval [parameter unit, e.g. N for alpha, kg for M].",
)
@click.option("--to", "stop", type=FINITE, required=True, help="End of the parameter interval [parameter unit].")
@click.option("--alpha", type=FINITE, default=None, help="Forcing amplitude [N] (default 17).")
@click.option("--fe", type=FINITE, default=None, help="Forcing frequency [Hz] (default 2.5).")
@click.option("--M", "M_", type=FINITE, default=None, help="Oscillator mass M = M1 + M2 [kg] (default 10.9).")
@click.option(
    "--set",
    "sets",
    multiple=True,
    metavar="NAME=VALUE",
    help="Any other model parameter, SI units (see `pendsweep params`), e.g. --set b1=0.",
)
@click.option(
    "--model",
    "model_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="JSON file of model parameters.",
)
@click.option(
    "--start",
    "start_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help='Start orbit: a sweep result (.parquet; the point nearest --start-value) or JSON {"value", "section" [m, m/s, rad, rad/s], "period"}. Default: the semi-trivial solution at --from.',
)
@click.option(
    "--start-value",
    type=FINITE,
    default=None,
    help="Parameter value [parameter unit] of the sweep point to start from (default --from).",
)
@click.option(
    "--eps",
    type=FINITE,
    default=1e-3,
    show_default=True,
    help="Damping sign smoothing sgn(w) ~ tanh(w/eps) [rad/s]; 0 holds the sign per step (non-smooth with b1 > 0).",
)
@click.option(
    "--dt",
    type=FINITE,
    default=1e-3,
    show_default=True,
    help="RK4 step [s], adjusted to a whole number of steps per forcing period.",
)
@click.option(
    "--ds",
    type=FINITE,
    default=0.02,
    show_default=True,
    help="First arclength step [-] (state in units of l, l w_e, rad, w_e; parameter in units of |to - from|).",
)
@click.option("--ds-max", type=FINITE, default=0.05, show_default=True, help="Largest arclength step [-].")
@click.option(
    "--max-points", type=click.IntRange(min=1), default=400, show_default=True, help="Points per direction and branch."
)
@click.option(
    "--max-period",
    type=click.IntRange(min=1),
    default=4,
    show_default=True,
    help="Largest orbit period reached by branch switching at period doublings [forcing periods].",
)
@click.option(
    "--tol",
    "newton_tol",
    type=FINITE,
    default=1e-10,
    show_default=True,
    help="Newton tolerance on the scaled update and residual [-].",
)
@click.option(
    "-o",
    "--output",
    "json_path",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Result JSON (default results/continue-PARAMETER.json).",
)
@click.option(
    "--json",
    "json_path_old",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    hidden=True,
    callback=lambda ctx, param, value: _deprecated_json(value),
)
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Also draw the branches here (.png/.pdf/.svg).",
)
@click.option(
    "--overlay",
    "overlays",
    multiple=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Sweep result (.parquet) drawn under the branches in --plot (repeatable).",
)
@click.option(
    "--observable",
    type=click.Choice(["theta_peak", "theta_absmax", "theta_sec", "y_absmax"]),
    default="theta_peak",
    show_default=True,
    help="Vertical axis of --plot (angles in rad, y in m).",
)
@click.option(
    "--backend",
    type=click.Choice(["emulated", "substructured"]),
    default="emulated",
    show_default=True,
    help="Whose orbits: Eq. (11), or the simulated hybrid test's tick map (noise and quantisation off).",
)
@backend_option("as for sweeps, e.g. -B transport_delay=0.02 -B predictor_order=2 (--backend substructured).")
@click.option(
    "--progress/--no-progress", default=None, help="Progress bar on stderr (default: when stderr is a terminal)."
)
@apply_options(work_options())
def continue_command(
    parameter,
    start,
    stop,
    alpha,
    fe,
    M_,
    sets,
    model_file,
    start_file,
    start_value,
    eps,
    dt,
    ds,
    ds_max,
    max_points,
    max_period,
    newton_tol,
    json_path,
    json_path_old,
    plot_path,
    overlays,
    observable,
    backend,
    backend_opts,
    progress,
    max_work,
    yes,
):
    """Continue periodic orbits in PARAMETER from --from to --to (both directions from the start).

    Shooting on the stroboscopic map over k forcing periods, the monodromy
    matrix from the variational equations (same RK4 as the sweeps), Newton
    and pseudo-arclength continuation. Prints the bifurcations found (fold,
    period doubling, Neimark-Sacker; values in the parameter's unit) and
    switches onto the doubled branch at every period doubling up to
    --max-period. Exit 1 when Newton cannot converge at the start.

    With --backend substructured the orbits are those of the hybrid test's
    own loop (numerical model, prediction, delay, servo, rig), its monodromy
    by finite differences; PARAMETER may then also be transport_delay [s],
    servo_bandwidth [Hz], servo_damping or tau_hat [s].
    """
    from ..analysis.continuation import ContinuationError
    from ..analysis.continuation.run import (
        START_SHIFT_WARN,
        ContinuationConfig,
        run_continuation,
        start_from_file,
        write_json,
    )

    if json_path is not None and json_path_old is not None:
        raise ConfigError("give the result file once (-o/--output; --json is its old name)")
    json_path = json_path or json_path_old or Path(f"results/continue-{parameter}.json")
    json_path = check_output(json_path, "-o/--output", (".json",))
    check_output(plot_path, "--plot", FIGURE_SUFFIXES)
    model: dict[str, float] = {}
    if model_file is not None:
        # A full parameter file may hold the continued parameter; its value is not used (the interval is).
        model.update({k: v for k, v in load_model_file(model_file).items() if k not in _aliases(parameter)})
    options = {
        f"--{name}": (name, value) for name, value in (("alpha", alpha), ("fe", fe), ("M", M_)) if value is not None
    }
    sets = model_sets(sets)
    twice = sorted({name for name, _ in options.values()} & sets.keys())
    if twice:
        raise ConfigError(f"--{twice[0]} and --set {twice[0]}={sets[twice[0]]:g} both fix {twice[0]}; give one")
    options.update({f"--set {k}": (k, v) for k, v in sets.items()})
    for option, (name, value) in options.items():
        if name in _aliases(parameter):
            raise ConfigError(
                f"{option} = {value:g}: {parameter} is the continued parameter; "
                "its range is --from/--to, not a model value"
            )
        model[name] = value
    section, value, period = None, None, 1
    if start_file is not None:
        section, value, period = start_from_file(start_file, parameter, start if start_value is None else start_value)
    elif start_value is not None:
        raise ConfigError("--start-value needs --start FILE")
    config = ContinuationConfig(
        parameter=parameter,
        start=start,
        stop=stop,
        model=model,
        start_section=section,
        start_value=value,
        period=period,
        eps=eps,
        dt=dt,
        ds=ds,
        ds_max=ds_max,
        max_points=max_points,
        max_period=max_period,
        newton_tol=newton_tol,
        backend=backend,
        backend_options=key_values(backend_opts, "-B"),
    )
    from ..engine.scan import check_work

    check_work(config.work(), work_limit(max_work, yes))
    for sweep in overlays:  # refuse unreadable or other-parameter sweeps before the run, not after
        swept = read_sweep_metadata(sweep, "--overlay")["config"].get("parameter")
        if swept != parameter:
            raise ConfigError(f"--overlay {str(sweep)!r} sweeps {swept!r}, not {parameter!r}")
    if backend != "emulated":
        from ..analysis.continuation.loop import SMOOTHED_OFF

        dropped = [name for name in SMOOTHED_OFF if name in config.backend_options]
        if dropped:
            click.echo(
                f"Note: {', '.join(dropped)} switched off: a continued loop is noise-free and exact "
                "(recorded in the result's config.smoothing)",
                err=True,
            )
    progress = sys.stderr.isatty() if progress is None else progress
    try:
        doc = run_continuation(config, progress=progress)
    except ContinuationError as exc:
        raise click.ClickException(str(exc)) from None
    write_json(doc, json_path)
    unit = doc["unit"]
    for i, (branch, ends) in enumerate(zip(doc["branches"], doc["branch_ends"])):
        pts = branch["points"]
        if pts:
            lo, hi = min(p["value"] for p in pts), max(p["value"] for p in pts)
            click.echo(
                f"branch {i}: period {branch['period']}, {len(pts)} points, {parameter} {lo:.6g} to {hi:.6g} {unit}, "
                f"{sum(p['stable'] for p in pts)} stable; ends: {', '.join(ends['ends'])}"
            )
    for bif in doc["bifurcations"]:
        click.echo(f"{bif['type']} at {parameter} = {bif['value']:.7g} {unit} (branch {bif['branch']})")
    if doc["start_shift"] > START_SHIFT_WARN:
        click.echo(
            f"warning: Newton moved the start orbit by {doc['start_shift']:.3g} (scaled: l, l w_e, rad, w_e) "
            f"to another orbit; check the start section and its period ({period})",
            err=True,
        )
    if eps == 0 and doc["config"]["model"]["b1"] > 0:
        click.echo(
            "note: --eps 0 holds sgn(thetadot) and takes its derivative as 0, so the Coulomb friction b1 "
            "drops out of the multipliers: stability and bifurcations of rest are those without it (a "
            "Coulomb pendulum at rest sticks); use --eps > 0 (default 1e-3 rad/s), see docs/continuation.md",
            err=True,
        )
    elif start_file is None and not doc["bifurcations"] and doc["config"]["model"]["b1"] > 0:
        click.echo(
            "note: with Coulomb friction (b1 > 0) rest does not lose stability; the swing is a separate "
            "branch: start on it with --start (a sweep result or an orbit), see docs/continuation.md"
        )
    click.echo(f"wrote {json_path}", err=True)
    if plot_path is not None:
        from ..figures.overlay import plot_any

        click.echo(f"plot -> {plot_any([*overlays, json_path], plot_path, observable)}")
