"""Figures of the emulated system: Figs. 8, 9 and 11 (a2), (b2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..backends import make_backend
from ..canvas import new_figure
from ..model.analytic import quenching_amplitudes
from ..model.params import FIG8, FIG9_CO, FIG9_PO
from ..studies.sweep import run_sweep
from ..studies.sweepfile import SWEEPS_DIR, load_sweep
from .plotting import plot_files
from .registry import figure


def fig8_traces(quick: bool):
    """Semi-trivial run from rest, then the same state kicked by theta = 0.1 rad."""
    backend = make_backend("emulated")
    settle, after = (40, 80) if quick else (150, 600)
    rest = backend.trace(FIG8, backend.initial_state(FIG8, 0, 0, 0, 0), settle)
    state = rest.iloc[-1][["y", "ydot", "theta", "thetadot"]].to_numpy(dtype=float).copy()
    state[2] += 0.1
    kicked = backend.trace(FIG8, state, after)
    kicked["t"] += rest["t"].iloc[-1]
    return rest, kicked


@figure("fig8")
def fig8(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 8: energy transfer at 2:1 resonance, alpha = 2 N, fe = 2.25 Hz."""
    rest, kicked = fig8_traces(quick)
    y1, y2 = quenching_amplitudes(FIG8)
    fig = new_figure((8, 5.5))
    ax_y, ax_t = fig.subplots(2, 1, sharex=True)
    for df, colour, label in (
        (rest, "tab:blue", "ST (from rest)"),
        (kicked, "tab:red", r"kicked, $\theta$ += 0.1 rad"),
    ):
        ax_y.plot(df["t"], 1e3 * df["y"], color=colour, lw=0.4, label=label)
        ax_t.plot(df["t"], df["theta"], color=colour, lw=0.4)
    for value, style, name in ((y1, "--", r"$y_{1max}$"), (y2, ":", r"$y_{2max}$")):
        for sign in (1, -1):
            ax_y.axhline(sign * 1e3 * value, color="k", ls=style, lw=0.8, label=name if sign > 0 else None)
    nt = 1e3 * np.abs(kicked["y"].to_numpy()[-len(kicked) // 5 :]).max()
    ax_y.set_title(
        f"Fig. 8 (emulated): Eq. (10) y1max = {1e3 * y1:.2f} mm (paper 4.1), y2max = {1e3 * y2:.2f} mm (paper 0.42); "
        f"model NT state reaches {nt:.2f} mm",
        fontsize=8,
    )
    ax_y.set_ylabel("y [mm]")
    ax_y.legend(fontsize=7, loc="upper left", ncol=4)
    ax_t.set_ylabel(r"$\theta$ [rad]")
    ax_t.set_xlabel("t [s]")
    path = outdir / "fig8.png"
    fig.savefig(path, dpi=150)
    return [path]


@figure("fig9")
def fig9(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 9: periodic (alpha = 5 N) and chaotic (12 N) orbits at fe = 2.2 Hz."""
    backend = make_backend("emulated")
    transient, shown = (20, 10) if quick else (100, 20)
    fig = new_figure((9, 5.5))
    axes = fig.subplots(2, 2)
    for col, (params, name) in enumerate(((FIG9_PO, "PO, alpha = 5 N"), (FIG9_CO, "CO, alpha = 12 N"))):
        run = backend.run_point(params, backend.initial_state(params, 0, 0, 0.1, 0), transient, 1)
        trace = backend.trace(params, run.state, shown)
        axes[0, col].plot(trace["t"], 1e3 * trace["y"], lw=0.6)
        axes[0, col].set_title(f"Fig. 9 ({'ab'[col]}) {name}, fe = 2.2 Hz", fontsize=9)
        axes[0, col].set_ylabel("y [mm]")
        axes[1, col].plot(trace["t"], np.angle(np.exp(1j * trace["theta"])), lw=0.6, color="tab:red")
        axes[1, col].set_ylabel(r"$\theta$ [rad] (wrapped)")
        axes[1, col].set_xlabel("t [s] after the transient")
    path = outdir / "fig9.png"
    fig.savefig(path, dpi=150)
    return [path]


def _sweep_figure(name: str, outdir: Path, quick: bool) -> list[Path]:
    spec = load_sweep(SWEEPS_DIR / f"{name}.toml")
    config, output = spec.config, spec.output
    if quick:
        from dataclasses import replace

        config = replace(config, values=config.values[::10], transient_periods=10, record_periods=5)
        output = outdir / f"{name}-quick.parquet"
    run_sweep(config, output, n_jobs=-1, overwrite=quick)
    return [plot_files([output], outdir / f"{name}{'-quick' if quick else ''}.png", title=spec.description)]


@figure("fig11a")
def fig11a(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 11(a2): theta peaks against alpha, 0-45 N at fe = 2.5 Hz."""
    return _sweep_figure("fig11a", outdir, quick)


@figure("fig11b")
def fig11b(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 11(b2): theta peaks against M at alpha = 17 N, fe = 2.5 Hz."""
    return _sweep_figure("fig11b", outdir, quick)
