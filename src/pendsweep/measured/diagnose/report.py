"""The diagnosis's fifth stage, report: markdown, figures and the extended model's params file.

:func:`write_report` writes a whole-record (or one part's) :class:`~.judge.Diagnosis`;
:func:`write_parts_report` a part-by-part :class:`~.judge.PartsDiagnosis`: the transfer
system's figure and table, and one :func:`write_report` per replayed part.
"""

from __future__ import annotations

import cmath
import json
import math
from pathlib import Path

import numpy as np

from ...canvas import legend_right
from ..records import UNITS
from .effects import ACTUATOR_CAUSES, EFFECTS, PART_OF, model_file, split_values
from .fit import CHANNEL_RATIO
from .identify.oscillator import SEPARABLE_VIF
from .identify.transfer import MODELS, TransferIdentification
from .identify.transfer import UNITS as TRANSFER_UNITS
from .judge import Diagnosis, PartsDiagnosis
from .judge.tests import DERIVATIVE_RATIO, P_VALUE, UNEXPLAINED_RATIO
from .signatures import backbone, cross_correlation, extrema, residual_spectrum, summarize


def extended_params(diag: Diagnosis) -> dict[str, float]:
    """The extended model as a JSON-able mapping of ModelParams fields.

    The nominal model with the named cause's estimate applied when it is a
    ModelParams field; chain parameters (gain, theta_offset, tau, gain_Fs) and the
    record's forcing (alpha, fe) are not model physics and are left out.
    """
    values = dict(diag.replay.nominal)
    if diag.best is not None:
        values.update(diag.best.estimate)
        # The numerical M1 = M - M2 and C1 = C - C2 are code: a different
        # platform changes the complete system's totals.
        if "M2" in diag.best.estimate:
            values["M"] = diag.replay.nominal["M"] - diag.replay.nominal["M2"] + values["M2"]
        if "C2" in diag.best.estimate:
            values["C"] = diag.replay.nominal["C"] - diag.replay.nominal["C2"] + values["C2"]
    model, _ = split_values(values)
    return model_file(model)


def _figures(diag: Diagnosis, outdir: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    rp = diag.replay
    t = rp.t
    ext = diag.best or diag.nominal
    files = []
    units = UNITS

    fig, axes = plt.subplots(len(rp.channels), 1, figsize=(10, 3 * len(rp.channels)), sharex=True, squeeze=False)
    for ax, c in zip(axes[:, 0], rp.channels):
        ax.plot(t, rp.meas[c], "k.", ms=1.5, label="measured")
        ax.plot(t, diag.nominal.sim[c], "C0-", lw=0.8, label="nominal")
        if diag.best:
            ax.plot(t, ext.sim[c], "C3--", lw=0.8, label=f"extended ({diag.cause})")
        _shade_compared(ax, rp)
        ax.set_ylabel(f"{c} [{units[c]}]")
    legend_right(axes[0, 0], fontsize=8)
    axes[-1, 0].set_xlabel("t [s]")
    files.append(_save(fig, outdir / "measured_vs_models.png"))

    fig, axes = plt.subplots(len(rp.channels), 1, figsize=(10, 3 * len(rp.channels)), sharex=True, squeeze=False)
    for ax, c in zip(axes[:, 0], rp.channels):
        ax.plot(t, diag.nominal.sim[c] - rp.meas[c], "C0-", lw=0.6, label="nominal")
        ax.plot(t, ext.sim[c] - rp.meas[c], "C3-", lw=0.6, label="extended")
        _shade_compared(ax, rp)
        ax.set_ylabel(f"residual {c} [{units[c]}]")
    legend_right(axes[0, 0], fontsize=8)
    axes[-1, 0].set_xlabel("t [s]")
    files.append(_save(fig, outdir / "residuals.png"))

    ncol = 2 if rp.kind == "free_decay" else 3
    fig, axes = plt.subplots(1, ncol + 1, figsize=(4.2 * (ncol + 1), 3.6))
    ax = axes[0]
    for c in rp.channels:
        for fit, style in ((diag.nominal, "-"), (ext, "--")):
            res = (fit.sim[c] - rp.meas[c]) / rp.scale[c]
            if np.all(np.isfinite(res)):
                sp = residual_spectrum(res, rp.dt)
                ax.semilogy(
                    sp.frequency, sp.psd, style, lw=0.8, label=f"{c} {'nominal' if fit is diag.nominal else 'extended'}"
                )
    ax.set_xlim(0, min(20.0, 0.5 / rp.dt))
    ax.set_xlabel("f [Hz]")
    ax.set_title("spectra of residual / std(channel)", fontsize=9)
    if ax.get_legend_handles_labels()[0]:  # no curve when every residual is non-finite
        legend_right(ax)
    k = 1
    if rp.kind != "free_decay":
        ax = axes[k]
        for c in rp.channels:
            res = diag.nominal.sim[c] - rp.meas[c]
            if np.all(np.isfinite(res)):
                xc = cross_correlation(res, rp.force, rp.dt, 0.1)
                ax.plot(xc.lag, xc["corr"], label=c)
        ax.set_xlabel("lag [s]")
        ax.set_title("corr(nominal residual, Fe)", fontsize=9)
        if ax.get_legend_handles_labels()[0]:
            legend_right(ax)
        k += 1
    ax, ax2 = axes[k], axes[k + 1]
    if "theta" not in rp.meas or "theta" in rp.constant:  # no swing compared (numerical part; pendulum at rest)
        why = "theta constant: no swing" if "theta" in rp.meas else "no pendulum in this part"
        for a in (ax, ax2):
            a.text(0.5, 0.5, why, ha="center", va="center", transform=a.transAxes)
            a.set_axis_off()
        files.append(_save(fig, outdir / "signatures.png"))
        return files
    ex_m = extrema(t, rp.meas["theta"], 3 * rp.noise["theta"] + 0.005)
    lines = ("-", "--") if rp.kind == "free_decay" else ("", "")  # forced swings: clouds, not curves
    for label, theta, style in (
        ("measured", rp.meas["theta"], "k."),
        ("nominal", diag.nominal.sim["theta"], "C0." + lines[0]),
        ("extended", ext.sim["theta"], "C3x" + lines[1]),
    ):
        if not np.all(np.isfinite(theta)):
            continue
        ex = extrema(t, theta, 3 * rp.noise["theta"] + 0.005)
        if len(ex) < 3:
            continue
        amp = np.abs(ex.theta.to_numpy())
        ax.plot(0.5 * (amp[:-1] + amp[1:]), amp[:-1] - amp[1:], style, ms=3, lw=0.8, label=label)
        bb = backbone(ex)
        ax2.plot(bb.amplitude, bb.frequency, style, ms=3, lw=0.8, label=label)
    ax.set_xlabel("amplitude [rad]")
    ax.xaxis.set_major_locator(MaxNLocator(nbins=4))  # a narrow panel: amplitudes like 0.0002 rad would touch
    ax.set_ylabel("decrement per half cycle [rad]")
    ax.set_title("decay: constant = Coulomb, proportional = viscous", fontsize=9)
    ax.legend(fontsize=7)
    if len(ex_m):
        a = np.linspace(0, np.abs(ex_m.theta).max(), 50)
        f0 = math.sqrt(rp.nominal["g"] / rp.nominal["l"]) / (2 * math.pi)
        ax2.plot(a, f0 * (1 - a * a / 16), "0.6", lw=0.8, label="ideal pendulum (nominal l)")
    ax2.set_xlabel("amplitude [rad]")
    ax2.set_ylabel("swing frequency [Hz]")
    ax2.set_title("amplitude-dependent frequency", fontsize=9)
    ax2.legend(fontsize=7)
    files.append(_save(fig, outdir / "signatures.png"))
    return files


def _shade_compared(ax, rp) -> None:
    """Grey out the samples left out of the comparison (no motion)."""
    idle = ~rp.moving
    if idle.any():
        edges = np.flatnonzero(np.diff(np.concatenate([[0], idle.astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            ax.axvspan(rp.t[a], rp.t[b - 1], color="0.9", zorder=0)


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")  # the legends sit right of the panels
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def write_report(diag: Diagnosis, outdir: Path, source: str) -> list[Path]:
    """Write ``report.md``, its figures and ``extended.json`` into ``outdir``."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    rp = diag.replay
    js = diag.to_json()
    files = _figures(diag, outdir)
    params_file = outdir / "extended.json"
    params_file.write_text(json.dumps(extended_params(diag), indent=1, sort_keys=True))
    files.append(params_file)
    sig = summarize(rp, diag.nominal.sim)
    method = (
        "single shooting over the whole record, initial angle and velocity fitted with every model"
        if rp.kind == "free_decay"
        else f"short-horizon prediction error: {len(rp.segments)} segments of about {rp.horizon:g} s, "
        "each started from the measured state (Savitzky-Golay estimates)"
    )
    val = js["validation"]
    if val["method"] == "leave-one-record-out":
        split = (
            f"Validation: leave-one-record-out over {len(val['records'])} records (physics fitted on the others, "
            "the left-out record's initial state and chain parameters on itself)."
        )
    else:
        split = (
            f"Validation: blocked cross-validation, {val['folds']} folds over {val['blocks']} contiguous blocks of "
            f"{val['block_seconds']:.3g} s (fold k holds out blocks k, k + {val['folds']}, ...), over the "
            f"{val['compared_seconds']:.3g} s of the {val['record_seconds']:.3g} s record where the data move"
            + (
                f"; constant channel(s) {', '.join(val['constant_channels'])} compared by their level"
                if val["constant_channels"]
                else ""
            )
            + "."
        )
    lines = [
        f"# Diagnosis of `{source}`",
        "",
        f"Kind `{rp.kind}`, {len(diag.problem.replays)} record(s); first: {rp.n} samples at {1 / rp.dt:g} Hz, "
        f"channels {', '.join(rp.channels)}. Comparison: {method}. {split}",
        "",
        "## Verdict",
        "",
        f"**cause: `{js['cause']}`**"
        + (f" — {', '.join(EFFECTS[c].meaning for c in diag.best.causes)}" if diag.best else ""),
        "",
        "| quantity | value |",
        "|---|---|",
        f"| cross-validated NRMSE, nominal (error_before) | {_fmt(js['error_before'])} |",
        f"| cross-validated NRMSE, verdict model (error_after) | {_fmt(js['error_after'])} |",
        f"| gain = 1 - after/before | {_fmt(js['gain'])} |",
        f"| explained share of the nominal's excess squared error | {_fmt(js['explained_share'])} |",
        f"| noise floor (sensor-noise NRMSE from the data) | {_fmt(diag.noise_floor)} |",
        f"| unexplained (after^2 > {UNEXPLAINED_RATIO[rp.kind]:g} x floor^2"
        + (f", or a channel's > {CHANNEL_RATIO[rp.kind]:g} x its noise^2" if rp.kind in CHANNEL_RATIO else "")
        + f") | {js['unexplained']} |",
        "| residual / noise variance per sensor channel | "
        + ", ".join(f"{c} {_fmt(v)}" for c, v in js["residual_to_noise"].items())
        + " |",
    ]
    if val["method"] == "leave-one-record-out":
        for name, e0, e1 in zip(val["records"], val["cross_record_error_nominal"], val["cross_record_error"]):
            lines.append(
                f"| cross-record prediction NRMSE of `{name}`, nominal -> verdict | {_fmt(e0)} -> {_fmt(e1)} |"
            )
    for c in diag.best.causes if diag.best else ():
        for k in diag.best.keys_of(c):
            lines.append(
                f"| estimate {k} [{EFFECTS[c].unit}] | {_fmt(js['estimate'][k])} ± {_fmt(js['uncertainty'][k])} |"
            )
    for key, label in (("first_round", "the best single cause"), ("second_round", "the best pair")):
        t = diag.tests.get(key)
        if t:
            zs = ", ".join(f"{c}: {_fmt(z)} (needed >= {t['z_needed'][c]:.3g})" for c, z in t["z"].items())
            lines += [
                "",
                f"Tests of {label} `{t['model']}` against `{t['against']}`: explained share {_fmt(t['explained_share'])} "
                f"(needed >= {t['share_needed']:g}); block Wilcoxon p = {_fmt(t['p_value'])} (needed < {t['p_needed']:g}); "
                f"|change| / fit uncertainty {zs} (same sign in every fold: "
                f"{all(t['folds_agree'].values())}); passed: {t['passed']}"
                + (
                    f"; beats the single cause with the actuator delay freed: {t['chain_ok']}"
                    if "chain_check" in t
                    else ""
                )
                + ".",
            ]
    lines += [
        "",
        "## What remains",
        "",
        "Out-of-fold residual of the verdict model (peaks as multiples of the reference "
        "frequency with their share of the residual power; lag-1 autocorrelation; largest correlation with the inputs):",
        "",
    ]
    for rec_name, rec in js["residual_signature"].items():
        for c, e in rec.items():
            if not isinstance(e, dict):
                continue
            peaks = ", ".join(
                f"{p['multiple']:.3g} {rec['reference']} ({100 * p['power_share']:.0f} %)" for p in e["peaks"]
            )
            corr = ", ".join(
                f"{k[5:]} {_fmt(v)}" for k, v in e.items() if k.startswith("corr_") and not k.endswith("_lag_s")
            )
            lines.append(
                f"- `{rec_name}` {c}: rms {_fmt(e['rms'])}, lag-1 {_fmt(e['lag1'])}; peaks {peaks}; corr {corr}"
            )
    tied = diag.tied_with()
    if tied:
        reasons = diag.tie_reasons()
        lines += [
            "",
            f"Not distinguishable on this record from: {', '.join(f'`{t}`' for t in tied)} (the verdict does "
            f"not beat them on the held-out blocks, signed-rank p >= {P_VALUE:g}, in the pooled error nor in "
            "units of each channel's noise).",
        ]
        lines += [f"- `{t}`: {reasons[t]}." for t in tied if t in reasons]
    lines += _identification_lines(diag)
    lines += [
        "",
        "## Candidates (sorted by cross-validated NRMSE)",
        "",
        "| cause | estimate | ± | cross-validated NRMSE | BIC (fit) | status |",
        "|---|---|---|---|---|---|",
    ]
    for c in diag.candidates:
        est = ", ".join(f"{p} = {_fmt(v)}" for p, v in c.estimate.items())
        stated = diag.stated_uncertainty(c)
        err = ", ".join(_fmt(stated[p]) for p in c.estimate)
        status, reasons = diag.status(c)
        why = f"{status}: {'; '.join(reasons)}" if reasons else status
        lines.append(f"| `{c.cause}` | {est} | {err} | {_fmt(c.error_cv)} | {c.bic:.1f} | {why} |")
    lines.append(f"| (nominal) | | | {_fmt(diag.nominal.error_after)} | {diag.nominal.bic:.1f} | |")
    lines += ["", "## Signature diagnostics (nominal model)", "", "| signature | value |", "|---|---|"]
    lines += [f"| {k} | {_fmt(v)} |" for k, v in sig.items()]
    lines += [
        "",
        "Decrement per half cycle is fitted as c0 + c1 A + c2 A^2: a dominant constant share points to Coulomb friction, "
        "a proportional one to viscous damping, a quadratic one to air drag. A residual mean or a turning-point midline "
        "away from zero points to an angle offset; a peak of corr(residual, Fe) away from zero lag to a delay.",
        "",
        "![measured vs models](measured_vs_models.png)",
        "",
        "![residuals](residuals.png)",
        "",
        "![signatures](signatures.png)",
        "",
        "## Extended model",
        "",
        "`extended.json` holds every ModelParams field of the extended model; run a sweep with it by "
        "`pendsweep sweep ... --model extended.json`. Measurement-chain parameters (gain, theta_offset, tau, gain_Fs) are not "
        "physics of the system and are not in the file: correct the recorded force by gain, the angle by theta_offset.",
    ]
    report = outdir / "report.md"
    report.write_text("\n".join(lines) + "\n")
    return [report] + files


def _identification_lines(diag: Diagnosis) -> list[str]:
    """The report's section on what the records hold for the oscillator (:mod:`.identify.oscillator`), if any."""
    found = [(rp.record.name, i) for rp, i in zip(diag.problem.replays, diag.identified) if i is not None]
    if not found:
        return []
    lines = [
        "",
        "## What the record holds for the oscillator (before any replay)",
        "",
        "Starts of the oscillator's fits, from the force's tones (or sweep), the response at each and any "
        "transient (`identify/oscillator.py`); each parameter fitted alone with the others nominal, and K, M, C together:",
        "",
        "| record | content | K alone [N/m] | M alone [kg] | K, M, C together | K-M inflation | K-k3 inflation |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, i in found:
        together = ", ".join(f"{k} = {_fmt(i.estimates[k])} ± {_fmt(i.stderr[k])}" for k in ("K", "M", "C"))
        lines.append(
            f"| `{name}` | {i.content()} | {_fmt(i.alone['K'])} | {_fmt(i.alone['M'])} | {together} | "
            f"{_fmt(i.inflation['M'])} | {_fmt(i.inflation['k3'])} |"
        )
    lines += [
        "",
        "Receptance at each tone (|Y/F| [m/N], phase [deg]): "
        + "; ".join(
            f"{t.frequency:.3g} Hz: {_fmt(abs(t.receptance))}, {math.degrees(cmath.phase(t.receptance)):.1f}"
            for _, i in found
            for t in i.tones
        ),
        "",
        f"A variance inflation of {SEPARABLE_VIF:.0e} or more means the two columns are multiples of each other on "
        "this record (one frequency in steady state): the record cannot separate the pair, whatever the fits say.",
    ]
    return lines


def plot_envelopes(curves: dict[str, tuple[np.ndarray, np.ndarray]], path: Path) -> Path:
    """Measured (dots) and simulated (lines) turning-point amplitudes against time.

    ``curves`` maps a label to ``(measured, simulated)`` arrays of shape (k, 2)
    holding ``t [s], amplitude [rad]``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for i, (label, (meas, sim)) in enumerate(curves.items()):
        ax.plot(meas[:, 0], np.rad2deg(meas[:, 1]), "o", ms=3, color=f"C{i}", label=f"{Path(label).name} measured")
        ax.plot(sim[:, 0], np.rad2deg(sim[:, 1]), "-", color=f"C{i}", lw=1, label="simulated")
    ax.set_xlabel("t from the first fitted turning point [s]")
    ax.set_ylabel("amplitude [deg]")
    ax.legend(fontsize=7)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    return _save(fig, Path(path))


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


def parts_extended_params(diag: PartsDiagnosis) -> dict[str, float]:
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
                f"Not distinguishable on this record from `{cause}` ({name} = {value:.5g} {TRANSFER_UNITS[name].split(' ')[0]}, the "
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
            + " | ".join(f"{k} [{TRANSFER_UNITS[k].split(' ')[0]}]" for k in MODELS["second_order"][1])
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
    params_file.write_text(json.dumps(parts_extended_params(diag), indent=1, sort_keys=True))
    report = outdir / "report.md"
    report.write_text("\n".join(lines) + "\n")
    return [report, params_file] + files


def _param_of(cause: str) -> str:
    return ACTUATOR_CAUSES[cause][0] if cause in ACTUATOR_CAUSES else EFFECTS[cause].param


def _meaning(cause: str) -> str:
    return ACTUATOR_CAUSES[cause][2] if cause in ACTUATOR_CAUSES else EFFECTS[cause].meaning
