"""Measured-data commands: ``diagnose``, ``fit-damping`` and ``synth``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

from ..errors import ConfigError
from ._app import ANGLE, FINITE, PATH, RATE, SEED, FiniteFloat, main
from ._checks import check_input, check_memory, check_not_an_input, check_output, check_output_dir, positional_or_output
from ._executor import apply_options, work_options
from ._executor import max_work as work_limit


def _pairs(items: tuple[str, ...], what: str) -> dict[str, float]:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"{what} {item!r} must look like NAME=VALUE")
        try:
            number = float(value)
        except ValueError:
            raise ConfigError(f"{what} {item!r}: {value!r} is not a number") from None
        if not math.isfinite(number):
            raise ConfigError(f"{what} {item!r}: {value!r} is not finite")
        out[name.strip()] = number
    return out


@main.command()
@click.argument("data", nargs=-1, required=True, type=PATH)
@click.option("--json", "json_out", type=PATH, help="Write the verdict JSON here (.json).")
@click.option(
    "--report",
    "report_dir",
    type=PATH,
    help="Write report.md, figures and extended.json into this folder.",
)
@click.option(
    "--horizon",
    type=FiniteFloat(1e-3, 1e5, "s"),
    default=None,
    help="Short-horizon segment length for forced and substructured records [s] (default 4).",
)
@click.option(
    "--folds",
    type=click.IntRange(2, 20),
    default=5,
    show_default=True,
    help="Cross-validation folds of one record [-] (several records: leave one record out).",
)
@click.option("--cause", "causes", multiple=True, help="Restrict the candidates to these causes (repeatable).")
@click.option(
    "-j",
    "--jobs",
    type=int,
    default=1,
    show_default=True,
    help="Candidates fitted in parallel (threads; -1: all cores, as in every command).",
)
@click.option(
    "--model",
    "model_file",
    type=PATH,
    help="JSON of ModelParams fields replacing the records' nominal model (e.g. from fit-damping --params-out).",
)
@click.option(
    "--method",
    type=click.Choice(["parts", "closed-loop"]),
    default="parts",
    show_default=True,
    help="Substructured records: identify the transfer system and replay the physical substructure and the "
    "numerical model each on its own (parts), or replay the whole loop with the actuator as a pure delay (closed-loop).",
)
@click.option(
    "--session",
    type=click.IntRange(0),
    default=None,
    help="Client session of a `pendsweep site` log to diagnose (default: the last).",
)
@apply_options(work_options())
def diagnose(data, json_out, report_dir, horizon, folds, causes, jobs, model_file, method, session, max_work, yes):
    """Compare measured records with their nominal model and name the missing effect.

    DATA is one or more format-v1 records (.csv with a .json sidecar, or
    .parquet), raw free-swing .txt files, `pendsweep site` logs or
    substructured `pendsweep trace` files. Several records are taken as one
    rig: physical parameters are fitted jointly (initial states and
    measurement-chain parameters per record) and validated by leave-one-record-out
    prediction. Substructured records and site logs are diagnosed part by part:
    transfer system (actuator, load cell, encoder), physical substructure and
    numerical model (docs/measured-data.md). Prints the verdict JSON.
    """
    from ..engine.scan import check_jobs, check_work
    from ..measured.diagnose.judge import PartsDiagnosis
    from ..measured.diagnose.pipeline import diagnose_records, diagnosis_work_of
    from ..measured.diagnose.report import write_parts_report, write_report
    from ..measured.records import read_record
    from ._sweep_options import load_model_file

    for path in data:
        check_input(path, "record")
    check_output(json_out, "--json", (".json",))
    check_not_an_input(json_out, "--json", data)
    check_output_dir(report_dir, "--report")
    model = load_model_file(model_file) if model_file is not None else None
    records = [read_record(p, session) for p in data]
    if model is not None:
        for record in records:
            record.params = record.params.replace(**model)
    check_jobs(jobs)
    wanted = list(causes) or None
    check_work(diagnosis_work_of(records, wanted, method), work_limit(max_work, yes), "diagnosis", "replays")
    diag = diagnose_records(records, wanted, jobs, horizon, folds, method)
    text = json.dumps(diag.to_json(), indent=1)
    if json_out:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(text + "\n")
    if report_dir:
        if isinstance(diag, PartsDiagnosis):
            write_parts_report(diag, report_dir, ", ".join(map(str, data)))
        else:
            write_report(diag, report_dir, ", ".join(map(str, data)))
    click.echo(text)


#: Memory per sample of a synthetic record while it is built and written [bytes]: about ten channels
#: of 8 bytes, held as arrays, a table and the text being written.
RECORD_BYTES_PER_SAMPLE = 320


@main.command()
@click.argument("out", type=PATH, required=False)
@click.option("-o", "--output", type=PATH, default=None, help="Record to write, .csv or .parquet (or as OUT).")
@click.option(
    "--kind",
    type=click.Choice(["free_decay", "forced", "substructured"]),
    default="free_decay",
    show_default=True,
    help="Record kind.",
)
@click.option(
    "--effect",
    "effects",
    multiple=True,
    help="Hidden effect CAUSE=VALUE, VALUE in the parameter's unit (e.g. viscous_damping=2e-4 [kg m^2/s]); repeatable.",
)
@click.option(
    "--set",
    "params",
    multiple=True,
    metavar="NAME=VALUE",
    help="Nominal model override in SI units (default Table IV; Fig. 9(a) forcing for forced and substructured records); repeatable.",
)
@click.option("--param", "params_old", multiple=True, hidden=True, deprecated="use --set")
@click.option(
    "--duration",
    type=FiniteFloat(0.01, 1e5, "s"),
    default=20.0,
    show_default=True,
    help="Record length [s], 0.01 to 1e5.",
)
@click.option(
    "--rate", type=FiniteFloat(1.0, 1e6, "Hz"), default=500.0, show_default=True, help="Sample rate [Hz], 1 to 1e6."
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of the sensor noise (0 to 2**63-1).")
@click.option(
    "--theta0", "theta_init", type=ANGLE, default=None, help="Initial pendulum angle [rad], within +-10 pi (default 1)."
)
@click.option(
    "--thetadot0",
    "thetadot_init",
    type=RATE,
    default=None,
    help="Initial pendulum velocity [rad/s], within +-1000 (default 0).",
)
@click.option("--theta-init", "theta_init_old", type=ANGLE, default=None, hidden=True, deprecated="use --theta0")
@click.option(
    "--thetadot-init", "thetadot_init_old", type=RATE, default=None, hidden=True, deprecated="use --thetadot0"
)
@click.option(
    "--transient",
    type=FiniteFloat(0.0, 1e5, "s"),
    default=30.0,
    show_default=True,
    help="Forced and substructured records: time simulated before recording [s].",
)
@click.option(
    "--tone2",
    type=(FINITE, FiniteFloat(1e-3, 1e3, "Hz")),
    default=None,
    help="Forced and substructured records: a second force tone AMPLITUDE [N] FREQUENCY [Hz].",
)
def synth(out, output, kind, effects, params, params_old, duration, rate, seed, theta_init, thetadot_init,
          theta_init_old, thetadot_init_old, transient, tone2):  # fmt: skip
    """Write a seeded measured-like record (format v1) with hidden effects.

    The record, -o FILE (or OUT, the older positional spelling), ends in .csv
    (a .json sidecar is written next to it) or .parquet.
    """
    from ..measured.diagnose import synthesize
    from ..measured.records import write_record
    from ..model.params import FIG9_PO, TABLE_IV
    from ._checks import model_sets

    out, spelled = positional_or_output(out, output, "OUT")
    check_output(out, spelled, (".csv", ".parquet"))
    if Path(out).suffix.lower() == ".csv":
        check_output(Path(out).with_suffix(".json"), f"{spelled} (its .json sidecar)")
    check_memory(duration * rate * RECORD_BYTES_PER_SAMPLE, f"a record of {duration:g} s at {rate:g} Hz")
    theta_init = _one_of(theta_init, theta_init_old, "--theta0", "--theta-init", 1.0)
    thetadot_init = _one_of(thetadot_init, thetadot_init_old, "--thetadot0", "--thetadot-init", 0.0)
    base = TABLE_IV if kind == "free_decay" else FIG9_PO
    nominal = base.replace(**model_sets(params + params_old))
    record = synthesize(
        kind,
        nominal,
        _pairs(effects, "--effect"),
        duration,
        rate,
        seed,
        theta_init,
        thetadot_init,
        transient,
        tone2=tone2,
    )
    for f in write_record(record, out):
        click.echo(f"wrote {f}")


def _one_of(new, old, new_name: str, old_name: str, default: float) -> float:
    """The value of an option that also has a deprecated old spelling."""
    if new is not None and old is not None:
        raise ConfigError(f"give {new_name} once ({old_name} is its old name)")
    return default if new is None and old is None else (new if new is not None else old)


@main.command("fit-damping")
@click.argument("data", nargs=-1, required=True, type=PATH)
@click.option("--json", "json_out", type=PATH, help="Write the results JSON here (.json).")
@click.option(
    "--params-out",
    type=PATH,
    help="Write the fitted model as a ModelParams JSON (l = L, b_i = beta_i m L^2).",
)
@click.option(
    "--mass",
    type=FiniteFloat(1e-6, 1e3, "kg"),
    default=None,
    help="Pendulum mass m [kg] used to turn per-unit-inertia damping into b1-b3 for --params-out (default: the record's nominal m).",
)
@click.option(
    "--skip",
    type=click.IntRange(0, 10),
    default=1,
    show_default=True,
    help="Turning points skipped before the fit starts [-].",
)
@click.option(
    "--plot",
    type=PATH,
    help="Write a figure of measured and simulated envelopes (.png/.pdf/.svg).",
)
def fit_damping(data, json_out, params_out, mass, skip, plot):
    """The paper's appendix procedure on free swings: fit on the first DATA, predict the others.

    Prints beta1 [1/s^2], beta2 [1/s], beta3 [-] (damping per unit inertia),
    the equivalent length L [m], and the maximum relative envelope error of
    the fit and of each prediction (the paper reached <= 2 %).
    """
    from ..measured.diagnose.damping import fit_damping as run
    from ..measured.diagnose.damping import predict
    from ..measured.records import read_record
    from ._checks import FIGURE_SUFFIXES

    for p in data:
        check_input(p, "record")
    check_output(json_out, "--json", (".json",))
    check_output(params_out, "--params-out", (".json",))
    check_output(plot, "--plot", FIGURE_SUFFIXES)
    for out, option in ((json_out, "--json"), (params_out, "--params-out")):
        check_not_an_input(out, option, data)
    records = [read_record(p) for p in data]
    fit = run(records[0], skip)
    preds = {str(p): predict(fit, r, skip) for p, r in zip(data[1:], records[1:])}
    out = {
        "fitted_on": str(data[0]),
        "physics": fit.physics,
        "stderr": fit.stderr,
        "offset_rad": fit.nuisance["theta_offset"],
        "stages": fit.stages,
        "envelope_error": fit.envelope_error,
        "predictions": {
            p: {"envelope_error": v["envelope_error"], "offset_rad": v["nuisance"]["theta_offset"]}
            for p, v in preds.items()
        },
    }
    click.echo(f"fitted on {data[0]} ({fit.iterations} sensitivity iterations)")
    units = {"beta1": "1/s^2", "beta2": "1/s", "beta3": "-", "L": "m"}
    for stage, vals in fit.stages.items():
        click.echo(f"  {stage:32s} " + "  ".join(f"{k}={v:.4g}" for k, v in vals.items()))
    click.echo(
        "  final (sensitivity updating)    "
        + "  ".join(f"{k}={v:.4g}±{fit.stderr[k]:.2g} {units[k]}" for k, v in fit.physics.items())
    )
    click.echo(f"  max envelope error {100 * fit.envelope_error:.2f} %  (paper: <= 2 %)")
    for p, v in preds.items():
        click.echo(f"predicted {p}: max envelope error {100 * v['envelope_error']:.2f} %")
    if json_out:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(out, indent=1) + "\n")
    if params_out:
        from ..measured.diagnose.effects import model_file

        model = records[0].params.replace(**fit.model_params(mass if mass is not None else records[0].params.m))
        params_out.parent.mkdir(parents=True, exist_ok=True)
        params_out.write_text(json.dumps(model_file(model), indent=1, sort_keys=True) + "\n")
    if plot:
        from ..measured.diagnose.report import plot_envelopes

        plot_envelopes(
            {str(data[0]) + " (fit)": (fit.measured, fit.simulated)}
            | {p: (v["measured"], v["simulated"]) for p, v in preds.items()},
            plot,
        )
