"""Stability figures: Fig. 5 (Bode with margins), Fig. 6 (stability chart), theory against simulation."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..analysis.stability import (
    SampledLoop,
    delay_margin,
    loop_response,
    sampled_delay_margin,
    sampled_response,
    servo_delay_margin,
    simulated_delay_margin,
    simulated_growth,
    stability_chart,
)
from ..canvas import new_figure
from ..model.params import (
    FIG5_LOOP,
    FIG6_OMEGA_N,
    FIG6_ZETA,
    TABLE_II_FREQ_EXPERIMENT_PAPER,
    TABLE_II_FREQ_THEORY_PAPER,
    TABLE_II_LOOPS,
    TABLE_II_MODELS,
    TABLE_II_P,
    LoopParams,
)
from .registry import figure

#: The compensation check: Table II, p = 0.225, servo, first-order 5-point prediction by 18 ms.
COMPENSATED = SampledLoop(actuator="servo", predictor_order=1, predictor_points=5, tau_hat=0.018)


def bode_figure(loop: LoopParams, path: Path, sampled: SampledLoop | None = None) -> Path:
    """Bode diagram of ``F_s N_m`` with every crossover's phase margin and switch delay.

    With ``sampled``, the backend's loop at zero transport delay (hold, servo
    or Hermite actuator, load cell, predictor, filter) is drawn dashed up to
    the Nyquist frequency.
    """
    margin = delay_margin(loop)
    wn = math.sqrt(loop.K / loop.M1)
    w = np.geomspace(wn / 100.0, wn * 100.0, 4000)
    L = loop_response(loop, w)
    fig = new_figure((7.5, 6))
    ax_m, ax_p = fig.subplots(2, 1, sharex=True)
    ax_m.semilogx(w, 20 * np.log10(np.abs(L)), color="k", label=r"$F_s N_m$")
    ax_p.semilogx(w, np.degrees(np.unwrap(np.angle(L))), color="k")
    if sampled is not None:
        ws = w[w < math.pi / sampled.dt]
        Ls = sampled_response(loop, 0.0, sampled, ws)
        ax_m.semilogx(ws, 20 * np.log10(np.abs(Ls)), "--", color="tab:blue", label="backend loop, tau = 0")
        ax_p.semilogx(ws, np.degrees(np.unwrap(np.angle(Ls))), "--", color="tab:blue")
    ax_m.axhline(0.0, color="0.5", lw=0.8)
    ax_p.axhline(-180.0, color="0.5", lw=0.8)
    ax_p.axhline(180.0, color="0.5", lw=0.8, ls=":")
    for c in margin.crossings:
        colour = "tab:red" if c.destabilising else "tab:green"
        for ax in (ax_m, ax_p):
            ax.axvline(c.omega, color=colour, lw=0.8, ls="--")
        ax_m.annotate(
            f"$\\omega$ = {c.omega:.4g} rad/s\n$\\psi$ = {c.psi_deg:.1f}°\n$\\tau$ = {c.tau:.4g} s",
            (c.omega, 0.0), textcoords="offset points", xytext=(4 if c.destabilising else -80, -40), fontsize=7,
            color=colour,
        )  # fmt: skip
    verdict = (
        f"tau* = {margin.tau_star:.4g} s at {margin.omega_star:.4g} rad/s" if margin.has_number else margin.verdict
    )
    ax_m.set_title(
        f"M1 = {loop.M1:g} kg, C1 = {loop.C1:g} kg/s, K = {loop.K:g} N/m, m_s = {loop.ms:g} kg, "
        f"C2 = {loop.C2:g} kg/s: {verdict}",
        fontsize=8,
    )
    ax_m.set_ylabel("|F_s N_m| [dB]")
    ax_m.legend(fontsize=7, loc="lower right")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel(r"$\omega$ [rad/s]")
    fig.savefig(path, dpi=150)
    return path


@figure("fig5_margin")
def fig5_margin(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 5: phase margins of the caption's loop (switches at 0.222 s and 0.711 s)."""
    return [bode_figure(FIG5_LOOP, outdir / "fig5_margin.png")]


@figure("fig6_chart")
def fig6_chart(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 6: critical delay against p = m_s/M1 for C2 = 0 and C2 = C1."""
    p = np.linspace(0.005, 0.995, 100 if quick else 400)
    fig = new_figure((11, 4.2))
    axes = fig.subplots(1, 2)
    text = rf"$\omega_n$ = {FIG6_OMEGA_N:g} rad/s, $\zeta$ = {FIG6_ZETA:g} (section 2.4)"
    for ax, (wn, zeta, title) in zip(
        axes, ((FIG6_OMEGA_N, FIG6_ZETA, text), (math.sqrt(750.0), 10.0 / (2.0 * math.sqrt(12000.0)), "M1 = 4 kg, C1 = 10 kg/s, K = 3000 N/m (caption, Table II)"))
    ):  # fmt: skip
        for ratio, style, label in ((0.0, "-", "C2 = 0"), (1.0, "--", "C2/C1 = 1")):
            tau, _ = stability_chart(wn, zeta, ratio, p)
            ax.plot(p, np.where(np.isinf(tau), np.nan, tau), style, color="k", label=label)
            stable = p[np.isinf(tau)]
            if stable.size:
                ax.axvspan(0, stable.max(), color="0.9", zorder=0)
                ax.text(
                    stable.max() / 2,
                    0.02,
                    "stable for\nall delays\n(C2 = 0)",
                    ha="center",
                    fontsize=6,
                    transform=ax.get_xaxis_transform(),
                )
        ax.axvline(1.0, color="tab:red", lw=0.8)
        ax.set_yscale("log")
        ax.set_xlim(0, 1.05)
        ax.set_xlabel(r"p = m$_s$/M$_1$")
        ax.set_ylabel(r"$\tau_{max}$ [s]")
        ax.set_title(title, fontsize=8)
    table = [delay_margin(loop) for loop in TABLE_II_LOOPS]
    axes[1].plot(TABLE_II_P, [m.tau_star for m in table], "o", color="tab:blue", label="Table II p values")
    for ax in axes:
        ax.legend(fontsize=7)
    fig.suptitle("Fig. 6: maximum delay against mass ratio; p >= 1 is unstable for every delay (neutral)", fontsize=9)
    path = outdir / "fig6_chart.png"
    fig.savefig(path, dpi=150)
    return [path]


def validation_rows(quick: bool) -> list[dict]:
    """Theory against the substructured backend for the Table II sets (quick: the first set only)."""
    rows = []
    cases = list(zip(TABLE_II_P, TABLE_II_LOOPS, TABLE_II_MODELS))[: 1 if quick else None]
    for p, loop, model in cases:
        for actuator in ("delay", "servo"):
            exact = sampled_delay_margin(loop, SampledLoop(actuator=actuator), 0.3)
            theory = delay_margin(loop) if actuator == "delay" else servo_delay_margin(loop, 30.0, 0.7, hold=1e-3)
            sim = simulated_delay_margin(
                model, round(0.96 * exact.tau_star, 4), 0.02 * exact.tau_star, actuator=actuator, predictor_order=-1
            )
            rows.append(dict(p=p, actuator=actuator, theory=theory, exact=exact, sim=sim))
    return rows


@figure("stability_validation")
def stability_validation(outdir: Path, quick: bool) -> list[Path]:
    """Critical delay and frequency: continuous theory, exact sampled loop, backend simulation."""
    rows = validation_rows(quick)
    fig = new_figure((14, 4.2))
    ax_t, ax_w, ax_c = fig.subplots(1, 3)
    for actuator, colour in (("delay", "tab:blue"), ("servo", "tab:orange")):
        sel = [r for r in rows if r["actuator"] == actuator]
        p = [r["p"] for r in sel]
        ax_t.plot(p, [r["theory"].tau_star for r in sel], "-", color=colour, label=f"{actuator}: continuous theory")
        ax_t.plot(
            p, [r["exact"].tau_star for r in sel], "x", color=colour, ms=9, label=f"{actuator}: exact sampled loop"
        )
        ax_t.plot(p, [r["sim"].tau_star for r in sel], "o", mfc="none", color=colour, label=f"{actuator}: simulation")
        ax_w.plot(p, [r["theory"].omega_star for r in sel], "-", color=colour, label=f"{actuator}: theory")
        ax_w.plot(p, [r["sim"].omega_star for r in sel], "o", mfc="none", color=colour, label=f"{actuator}: simulation")
    ax_w.plot(TABLE_II_P, TABLE_II_FREQ_THEORY_PAPER, "k+", ms=10, label="paper, theoretical row")
    ax_w.plot(TABLE_II_P, TABLE_II_FREQ_EXPERIMENT_PAPER, "ks", mfc="none", label="paper, experimental row")
    ax_t.set_xlabel("p")
    ax_t.set_ylabel(r"critical transport delay $\tau^*$ [s]")
    ax_w.set_xlabel("p")
    ax_w.set_ylabel(r"instability frequency $\omega^*$ [rad/s]")
    for ax in (ax_t, ax_w):
        ax.legend(fontsize=6)
    # compensation: between the uncompensated and the compensated tau*, only the predictor keeps y* bounded
    loop, model = TABLE_II_LOOPS[0], TABLE_II_MODELS[0]
    none = sampled_delay_margin(loop, SampledLoop(actuator="servo"), 0.3)
    comp = sampled_delay_margin(loop, COMPENSATED, 0.3)
    tau = 0.5 * (none.tau_star + comp.tau_star)
    for cfg, colour, label in (
        (SampledLoop(actuator="servo"), "tab:red", "no prediction"),
        (COMPENSATED, "tab:green", "1st order, 5 points, tau_hat 18 ms"),
    ):
        g = simulated_growth(
            model, tau, actuator="servo", predictor_order=cfg.predictor_order, tau_hat=cfg.tau_hat or 0.0
        )
        ax_c.bar(label, g.sigma, color=colour)
    ax_c.axhline(0.0, color="k", lw=0.8)
    ax_c.set_ylabel(r"simulated growth rate of $y^*$ [1/s]")
    ax_c.set_title(
        f"p = 0.225, servo, transport delay {tau * 1e3:.1f} ms\n"
        f"tau* {none.tau_star * 1e3:.1f} ms without, {comp.tau_star * 1e3:.1f} ms with prediction",
        fontsize=8,
    )
    fig.suptitle("Stability boundary: theory against the substructured backend (Table II sets, C2 = C1)", fontsize=9)
    path = outdir / "stability_validation.png"
    fig.savefig(path, dpi=150)
    return [path]
