"""Basin maps, basin fractions against a parameter, and two-parameter maps (issue 14).

Plot functions are used by ``pendsweep basins --plot`` and ``pendsweep map
--plot``; the registered figures (``make figures``) run small versions of
the documented commands.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pandas as pd
from matplotlib import patheffects
from matplotlib.colors import ListedColormap
from matplotlib.patches import Patch

from ..canvas import legend_below, new_figure
from ..model.params import PARAM_SPECS
from ..studies.basins import BasinConfig, run_basins, scan_summary, survival
from ..studies.maps import MapConfig, hopf_boundaries, run_map
from .registry import figure

#: Colour per motion class; periodic orbits by period.
CLASS_COLOURS = {
    "semi-trivial": "0.85",
    "periodic-1": "tab:cyan",
    "periodic-2": "tab:blue",
    "periodic-3": "tab:olive",
    "periodic-4": "tab:green",
    "periodic-5": "gold",
    "periodic-6": "tab:pink",
    "periodic-7": "tab:brown",
    "periodic-8": "tab:purple",
    "rotating": "tab:orange",
    "unsettled": "tab:red",
    "n/a": "black",
}


#: A black outline under a line (a white line readable on dark images and on the white legend).
_OUTLINED = [patheffects.Stroke(linewidth=3.0, foreground="black"), patheffects.Normal()]


def _axis_label(parameter: str) -> str:
    return f"{parameter} [{PARAM_SPECS[parameter].unit}]"


def _colour(label: str) -> str:
    return CLASS_COLOURS.get(label, "tab:gray")


def plot_basin(rows: pd.DataFrame, summary: dict[str, Any], config: BasinConfig, output: Path) -> Path:
    """Basin map over (theta0, thetadot0) coloured by attractor, and the survival curves."""
    fig = new_figure((11, 4.6))
    ax, bx = fig.subplots(1, 2)
    table = summary["attractors"]

    def name(a: dict) -> str:
        if a["motion"] != "rotating":
            return a["motion"]
        cycle = f"cycle {a['period']}T" if a["period"] else "steady, section not periodic"
        return f"rotating {a['rotation_number']:+g} turn/T, {cycle}"

    names = [f"{name(a)} ({100 * a['fraction']:.1f}%)" for a in table]
    palette = [
        c for i, c in enumerate(matplotlib.colormaps["tab10"].colors) if i not in (3, 7)
    ]  # red, grey: kept for unsettled
    colours = [palette[i % len(palette)] for i in range(len(table))] + ["tab:red"]
    ids = rows["attractor"].to_numpy()
    index = np.where(ids < 0, len(table), ids)
    if config.sampling == "grid":
        nt, nd = config.grid
        image = index.reshape(nt, nd).T
        extent = [rows.theta0.min(), rows.theta0.max(), rows.thetadot0.min(), rows.thetadot0.max()]
        ax.imshow(
            image,
            origin="lower",
            aspect="auto",
            extent=extent,
            cmap=ListedColormap(colours),
            vmin=-0.5,
            vmax=len(colours) - 0.5,
            interpolation="nearest",
        )
    else:
        ax.scatter(rows.theta0, rows.thetadot0, c=[colours[i] for i in index], s=4, linewidths=0)
    handles = [Patch(color=colours[i], label=n) for i, n in enumerate(names)]
    handles.append(Patch(color="tab:red", label=f"unsettled ({100 * summary['unsettled']:.1f}%)"))
    legend_below(ax, handles=handles, ncol=2)  # every pixel of a basin image is data
    ax.set_xlabel(r"initial $\theta$ [rad]")
    ax.set_ylabel(r"initial $\dot\theta$ [rad/s]")
    ax.set_title(f"{config.parameter} = {summary['value']:g}, y = ẏ = 0, cap {config.max_periods} periods", fontsize=9)
    t = np.arange(0, config.max_periods + 1)
    for column, label in (
        ("escape_periods", "irregular (not within 0.05 of its cycle)"),
        ("settle_periods", "unsettled (cycle repeats to 1e-3)"),
    ):
        bx.semilogy(t, np.maximum(survival(rows[column].to_numpy(), t), 1e-5), label=label)
    esc = summary.get("escape")
    if esc:
        tt = np.linspace(esc["from"], esc["to"], 50)
        s0 = survival(rows["escape_periods"].to_numpy(), np.array([esc["from"]]))[0]
        bx.semilogy(
            tt,
            s0 * np.exp(-esc["rate"] * (tt - esc["from"])),
            "k--",
            lw=1,
            label=f"escape rate {esc['rate']:.4f} ± {esc['stderr']:.4f} /period",
        )
    bx.axvline(100, color="0.6", lw=0.8, ls=":")
    bx.set_ylim(max(0.5 / max(summary["runs"], 1), 1e-5), 1.2)
    bx.set_xlabel("forcing periods")
    bx.set_ylabel("fraction of starts")
    bx.legend(fontsize=7)
    fig.savefig(output, dpi=150, bbox_inches="tight")
    return output


def plot_scan(summary: dict[str, Any], output: Path) -> Path:
    """Stacked basin fractions per motion class against the parameter, and the unsettled fraction after 100 periods."""
    values = np.asarray(summary["values"])
    classes = sorted(summary["classes"], key=lambda c: list(CLASS_COLOURS).index(c) if c in CLASS_COLOURS else 99)
    fig = new_figure((10, 4.6))
    ax = fig.subplots()
    ax.stackplot(
        values,
        [summary["classes"][c] for c in classes],
        labels=classes,
        colors=[_colour(c) for c in classes],
        alpha=0.85,
    )
    for key, style, label in (
        ("unsettled_after_100", "k-", "unsettled (to 1e-3) after 100 periods"),
        ("irregular_after_100", "k--", "irregular after 100 periods"),
    ):
        ax.errorbar(
            values, summary[key], yerr=summary[key + "_stderr"], fmt=style, lw=1.2, ms=2, capsize=0, label=label
        )
    ax.set_xlim(values[0], values[-1])
    ax.set_ylim(0, 1)
    ax.set_xlabel(_axis_label(summary["parameter"]))
    ax.set_ylabel("fraction of starts (basin)")
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.savefig(output, dpi=150)
    return output


def draw_map_classes(ax, rows: pd.DataFrame, config: MapConfig, alpha: float = 1.0) -> tuple[list[str], list[float]]:
    """The map's motion classes as an image on ``ax``; returns the classes shown and the image's extent."""
    nx, ny = len(config.x_values), len(config.y_values)
    grid = rows.sort_values(["ix", "iy"])
    labels = grid["motion"].to_numpy().reshape(nx, ny).T
    present = [c for c in CLASS_COLOURS if (labels == c).any()] + sorted(set(labels.ravel()) - set(CLASS_COLOURS))
    code = np.vectorize({c: i for i, c in enumerate(present)}.get)(labels)
    extent = _edges(config.x_values) + _edges(config.y_values)
    ax.imshow(
        code,
        origin="lower",
        aspect="auto",
        extent=extent,
        interpolation="nearest",
        cmap=ListedColormap([_colour(c) for c in present]),
        vmin=-0.5,
        vmax=len(present) - 0.5,
        alpha=alpha,
    )
    return present, extent


def _edges(values) -> list[float]:
    """Outer edges of a grid of cell centres (a single value: a unit-wide cell)."""
    v = np.asarray(values)
    if v.size == 1:
        return [v[0] - 0.5, v[0] + 0.5]
    return [v[0] - (v[1] - v[0]) / 2, v[-1] + (v[-1] - v[-2]) / 2]


def plot_map(rows: pd.DataFrame, config: MapConfig, boundaries: pd.DataFrame | None, output: Path) -> Path:
    """Motion class and settled max |theta| over the grid, with the Eq. (12) and Floquet boundaries."""
    nx, ny = len(config.x_values), len(config.y_values)
    swing = rows.sort_values(["ix", "iy"])["theta_absmax"].to_numpy().reshape(nx, ny).T
    fig = new_figure((12, 4.8))
    axes = fig.subplots(1, 2)
    present, extent = draw_map_classes(axes[0], rows, config)
    legend_below(axes[0], handles=[Patch(color=_colour(c), label=c) for c in present])
    im = axes[1].imshow(
        swing, origin="lower", aspect="auto", extent=extent, interpolation="nearest", cmap="viridis", vmin=0, vmax=np.pi
    )
    fig.colorbar(im, ax=axes[1], label=r"settled max $|\theta|$ [rad]")
    for ax in axes:
        if boundaries is not None:
            other = [c for c in boundaries.columns if c not in ("analytic", "floquet")][0]
            for col, style, label in (
                # White on the image, outlined in black so that its legend entry shows on white too.
                ("analytic", dict(color="white", ls="--", lw=1.5, path_effects=_OUTLINED), "Eq. (12)"),
                ("floquet", dict(color="k", lw=1.0), "Floquet (b1 = b3 = 0)"),
            ):
                xy = (
                    (boundaries[col], boundaries[other])
                    if config.x == "alpha"
                    else (boundaries[other], boundaries[col])
                )
                ax.plot(*xy, label=label, **style)
            ax.set_xlim(extent[0], extent[1])
            ax.set_ylim(extent[2], extent[3])
        ax.set_xlabel(_axis_label(config.x))
        ax.set_ylabel(_axis_label(config.y))
    if boundaries is not None:
        legend_below(axes[1])
    axes[0].set_title(f"motion after ≤ {config.max_periods} periods from θ = {config.initial[0]:g} rad", fontsize=9)
    fig.savefig(output, dpi=150)
    return output


@figure("basin40")
def basin40(outdir: Path, quick: bool) -> list[Path]:
    """Basin map at alpha = 40 N, fe = 2.5 Hz (the paper's chaos), with survival curves."""
    grid = (24, 24) if quick else (120, 120)
    config = BasinConfig("alpha", (40.0,), {"fe": 2.5}, sampling="grid", grid=grid, max_periods=1000)
    df = run_basins(config)
    summary, rows = scan_summary(config, df)
    return [plot_basin(rows, summary, config, outdir / "basin40.png")]


@figure("basin_fractions")
def basin_fractions(outdir: Path, quick: bool) -> list[Path]:
    """Basin fractions against alpha at fe = 2.5 Hz and the fraction unsettled after 100 periods."""
    values = tuple(np.arange(30.0, 45.01, 3.0 if quick else 0.5))
    config = BasinConfig("alpha", values, {"fe": 2.5}, samples=40 if quick else 500, max_periods=1000)
    summary, _ = scan_summary(config, run_basins(config))
    return [plot_scan(summary, outdir / "basin_fractions.png")]


@figure("map_alpha_fe")
def map_alpha_fe(outdir: Path, quick: bool) -> list[Path]:
    """Motion class and max |theta| over (alpha, fe) with the Hopf boundaries."""
    n = 12 if quick else 100
    config = MapConfig(
        "alpha", tuple(np.linspace(0, 45, n)), "fe", tuple(np.linspace(2.0, 3.0, n)), max_periods=100 if quick else 300
    )
    return [plot_map(run_map(config), config, hopf_boundaries(config), outdir / "map_alpha_fe.png")]
