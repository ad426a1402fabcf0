"""The report of a part-by-part diagnosis: the transfer system's figure and table, and one report per part."""

from __future__ import annotations

import json
from pathlib import Path

from ...canvas import legend_right
from .chain import PartsDiagnosis
from .effects import EFFECTS, PART_OF, model_file, split_values
from .report import write_report
from .thresholds import DERIVATIVE_RATIO
from .transfer import MODELS, UNITS, TransferIdentification

#: Seconds of record shown in the transfer figure's close-up.
CLOSE_UP = 1.0


def plot_transfer(ident: TransferIdentification, path: Path, title: str = "") -> Path:
    """Command, measured and modelled platform displacement (a close-up), and each model's residual."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    problem = ident.problem
    t = problem.tc - problem.tc[0]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6.5))
    shown = (t >= t[-1] / 2) & (t <= t[-1] / 2 + CLOSE_UP)
    top.plot(t[shown], 1e3 * problem.command[shown], "0.5", lw=1.0, label="command y_cmd")
    top.plot(t[shown], 1e3 * problem.measured[shown], "k.", ms=2, label="measured y (LVDT)")
    top.plot(t[shown], 1e3 * ident.best.achieved[shown], "C3-", lw=1.0, label=f"modelled ({ident.selected})")
    top.set_ylabel("displacement [mm]")
    top.set_title(
        title
        or f"transfer system: effective delay {1e3 * ident.effective_delay()[0]:.2f} ms at "
        f"{ident.frequency:g} Hz (nominal {1e3 * ident.nominal.effective_delay(ident.frequency):.2f} ms)",
        fontsize=9,
    )
    legend_right(top, fontsize=8)
    idx = problem.idx
    for k, (name, fit) in enumerate(ident.fits.items()):
        r = problem.measured[idx] - fit.achieved[idx]
        bottom.plot(
            t[idx],
            1e6 * r,
            f"C{k}-",
            lw=0.5,
            alpha=0.8,
            label=f"{name}: held-out RMS {1e6 * fit.error_held_out:.1f} um",
        )
    bottom.axhline(0.0, color="k", lw=0.5)
    bottom.set_xlabel("t [s]")
    bottom.set_ylabel("measured - modelled [um]")
    legend_right(bottom, fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def extended_params(diag: PartsDiagnosis) -> dict[str, float]:
    """The extended model (ModelParams fields) with every named physical and numerical estimate applied."""
    first = (diag.numerical or diag.physical).problem.replays[0]
    nominal = first.nominal
    values = dict(nominal)
    for part in diag.diagnoses:
        if part.best is not None:
            values.update({k: v for k, v in part.best.estimate.items() if "@" not in k})
    # The numerical M1 = M - M2 and C1 = C - C2 are code: a different platform changes the totals.
    values["M"] = values["M"] - nominal["M2"] + values["M2"]
    values["C"] = values["C"] - nominal["C2"] + values["C2"]
    model, _ = split_values(values)
    return model_file(model)


def write_parts_report(diag: PartsDiagnosis, outdir: Path, source: str) -> list[Path]:
    """``report.md`` with the verdict per part and the transfer identification, a folder per replayed part."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    js = diag.to_json()
    files: list[Path] = []
    lines = [
        f"# Diagnosis of `{source}`, part by part",
        "",
        f"**Verdict: `{js['cause']}`**" + (" — unexplained residual left" if js["unexplained"] else ""),
        "",
        "| cause | part | estimate | uncertainty (1 sigma) | meaning |",
        "|---|---|---|---|---|",
    ]
    for c in diag.causes:
        keys = [k for k in js["estimate"] if k.split("@")[0] in (_param_of(c),)]
        for k in keys:
            lines.append(
                f"| {c} | {PART_OF[c]} | {js['estimate'][k]:.6g} | {js['uncertainty'].get(k, float('nan')):.3g} | {_meaning(c)} |"
            )
    if not diag.causes:
        lines.append("| none | | | | every part as nominal |")
    lines += ["", "## Transfer system (command y_cmd to platform motion y)", ""]
    for i, (ident, verdict) in enumerate(zip(diag.transfers, diag.transfer_verdicts)):
        figure = plot_transfer(ident, outdir / f"transfer{'' if len(diag.transfers) == 1 else i}.png")
        files.append(figure)
        eff, sigma = ident.effective_delay()
        lines += [
            f"Selected model: **{ident.selected}** (the simplest within 5 % of the best held-out mean square). "
            f"Effective delay at {ident.frequency:g} Hz: {1e3 * eff:.3f} +- {1e3 * sigma:.3f} ms "
            f"(nominal {1e3 * ident.nominal.effective_delay(ident.frequency):.3f} ms); "
            f"LVDT noise {1e6 * ident.noise:.1f} um. Actuator verdict: `{'+'.join(verdict['causes']) or 'none'}`.",
            *(
                f"Not distinguishable on this record from `{cause}` ({name} = {value:.5g} {UNITS[name].split(' ')[0]}, the "
                "nominal transport delay kept): the command holds too little above the forcing to tell them apart."
                for cause, (name, value) in verdict["tied_with"].items()
            ),
            *(
                f"Measured {column} against the motion that drives the specimen's replay: rms difference "
                f"{check['rms_difference']:.3g}, {check['ratio_to_noise']:.3g} x its noise variance"
                + (" (the rig did not move as modelled: flagged)" if check["ratio_to_noise"] > DERIVATIVE_RATIO else "")
                + "."
                for column, check in verdict.get("measured_derivatives", {}).items()
            ),
            "",
            "| model | "
            + " | ".join(f"{k} [{UNITS[k].split(' ')[0]}]" for k in MODELS["second_order"][1])
            + " | RMS fit [um] | RMS held-out [um] |",
            "|---|" + "---|" * (len(MODELS["second_order"][1]) + 2),
        ]
        for name, fit in ident.fits.items():
            cells = [
                f"{getattr(fit.actuator, k):.5g} +- {fit.stderr[k]:.2g}" if k in fit.stderr else ""
                for k in MODELS["second_order"][1]
            ]
            lines.append(
                f"| {name} | " + " | ".join(cells) + f" | {1e6 * fit.error_fit:.2f} | {1e6 * fit.error_held_out:.2f} |"
            )
        lines += ["", f"![transfer]({figure.name})", ""]
    for name in ("physical", "numerical"):
        part = getattr(diag, name)
        lines += [f"## {name.capitalize()} part", ""]
        if part is None:
            lines += [f"Not replayed: {diag.skipped[name]}.", ""]
            continue
        files += write_report(part, outdir / name, f"{source} ({name} part)")
        lines += [f"Verdict `{part.cause}`; see [{name}/report.md]({name}/report.md).", ""]
    params_file = outdir / "extended.json"
    params_file.write_text(json.dumps(extended_params(diag), indent=1, sort_keys=True))
    report = outdir / "report.md"
    report.write_text("\n".join(lines) + "\n")
    return [report, params_file] + files


def _param_of(cause: str) -> str:
    from .effects import ACTUATOR_CAUSES

    return ACTUATOR_CAUSES[cause][0] if cause in ACTUATOR_CAUSES else EFFECTS[cause].param


def _meaning(cause: str) -> str:
    from .effects import ACTUATOR_CAUSES

    return ACTUATOR_CAUSES[cause][2] if cause in ACTUATOR_CAUSES else EFFECTS[cause].meaning
