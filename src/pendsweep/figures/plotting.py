"""Bifurcation diagrams in the style of Fig. 11, drawn on :func:`pendsweep.canvas.new_figure`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.patches import Patch

from ..canvas import legend_right, new_figure
from ..engine.results import read_results
from ..errors import ConfigError
from ..model.params import PARAM_SPECS

#: Plotted observables with their axis labels.
OBSERVABLES = {
    "theta_peak": r"$\theta$ peak [rad]",
    "theta_absmax": r"max $|\theta|$ [rad]",
    "theta_sec": r"$\theta$ at forcing phase 0 [rad]",
    "y_absmax": "max |y| [m]",
}
#: Marker style per branch: continuation up/down, fresh starts, multistart.
BRANCH_STYLE = {
    "up": dict(color="tab:blue", marker="o", s=4, label="continue, up"),
    "down": dict(color="tab:orange", marker="x", s=9, label="continue, down"),
    "fresh": dict(color="black", marker=".", s=4, label="fresh start"),
    "multistart": dict(color="0.55", marker=".", s=2, label="multistart"),
}


def branch_label(df: pd.DataFrame, meta: dict[str, Any]) -> pd.Series:
    """Per-row branch: the continuation direction, or the mode for independent points."""
    mode = meta["config"]["mode"]
    if mode == "continue":
        return df["direction"]
    return pd.Series(mode, index=df.index)


def draw_bifurcation(
    ax: Axes,
    results: Sequence[tuple[pd.DataFrame, dict[str, Any]]],
    observable: str = "theta_peak",
) -> None:
    """Scatter ``observable`` against the swept parameter for every result set.

    Up and down continuation branches, fresh and multistart points get
    distinct markers; points whose status is not ``ok`` are marked with a red
    cross at the top of the axes.
    """
    if observable not in OBSERVABLES:
        raise ConfigError(f"unknown observable {observable!r}; choose from {', '.join(OBSERVABLES)}")
    parameters = {meta["config"]["parameter"] for _, meta in results}
    if len(parameters) != 1:
        raise ConfigError(f"cannot overlay sweeps of different parameters: {', '.join(sorted(parameters))}")
    parameter = parameters.pop()
    seen: set[str] = set()
    for df, meta in results:
        branches = branch_label(df, meta)
        for branch, style in BRANCH_STYLE.items():
            sel = (branches == branch) & (df["status"] == "ok")
            if not sel.any():
                continue
            label = style["label"] if branch not in seen else None
            seen.add(branch)
            kw = {k: v for k, v in style.items() if k != "label"}
            ax.scatter(df.loc[sel, parameter], df.loc[sel, observable], label=label, linewidths=0.6, **kw)
        bad = df.loc[df["status"] != "ok", parameter].unique()
        if len(bad):
            top = np.pi if observable.startswith("theta") else ax.get_ylim()[1]
            ax.scatter(bad, np.full(len(bad), top), color="red", marker="x", s=20, label="diverged/unstable")
    strips = draw_motion_bands(ax, results, parameter) if all("motion" in df for df, _ in results) else 0
    spec = PARAM_SPECS[parameter]
    ax.set_xlabel(f"{parameter} [{spec.unit}]  ({spec.doc})")
    ax.set_ylabel(OBSERVABLES[observable])
    if observable.startswith("theta") and observable != "theta_absmax":
        # Room under -pi for the class strips (each 3 % of the axes' height), so none covers a point.
        share = 0.045 + 0.03 * max(strips - 1, 0) if strips else 0.0
        ax.set_ylim(-np.pi - 2 * np.pi * share / (1 - share), np.pi)
        ax.set_yticks([-np.pi, -np.pi / 2, 0, np.pi / 2, np.pi], [r"$-\pi$", r"$-\pi/2$", "0", r"$\pi/2$", r"$\pi$"])
    ax.grid(alpha=0.3)
    legend_right(ax, fontsize=8, markerscale=2)


def plot_files(
    paths: Sequence[Path],
    output: Path,
    observable: str = "theta_peak",
    title: str | None = None,
    overlays: Sequence[Callable[[Axes], None]] = (),
) -> Path:
    """Draw the bifurcation diagram of one or more result files into ``output`` (PNG/PDF/SVG).

    ``overlays`` draw more on the same axes afterwards (e.g. continuation branches).
    """
    output = Path(output)
    if output.suffix.lower() not in {".png", ".pdf", ".svg"}:
        raise ConfigError(f"plot file {str(output)!r} must end in .png, .pdf or .svg")
    results = [read_results(Path(p)) for p in paths]
    fig = new_figure((7.5, 4.5))
    ax = fig.subplots()
    draw_bifurcation(ax, results, observable)
    for draw in overlays:
        draw(ax)
    if title is None:
        cfg = results[0][1]["config"]
        fixed = {k: v for k, v in cfg["model"].items() if k in ("alpha", "fe", "M", "C", "K") and k != cfg["parameter"]}
        title = f"{cfg['backend']} backend, {cfg['mode']} mode; " + ", ".join(
            f"{k} = {v:g} {PARAM_SPECS[k].unit}" for k, v in fixed.items()
        )
    ax.set_title(title, fontsize=9)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=150, bbox_inches="tight")  # the legends sit right of the axes
    return output


#: Band colour per motion family (``periodic-n`` share one colour and carry n as text).
MOTION_COLOURS = {
    "semi-trivial": "0.85",
    "transient": "tab:olive",
    "quasi-periodic": "tab:green",
    "periodic": "tab:cyan",
    "chaotic": "tab:red",
    "rotating": "tab:purple",
    "n/a": "white",
    "mixed": "0.4",
}


def point_motions(df: pd.DataFrame, branches: pd.Series, parameter: str) -> dict[str, pd.Series]:
    """Per branch, one motion per parameter value (``mixed`` where multistarts disagree)."""
    out = {}
    for branch in branches.unique():
        sel = df[branches == branch]
        per_value = sel.groupby(parameter)["motion"].agg(lambda m: m.iloc[0] if m.nunique() == 1 else "mixed")
        out[branch] = per_value.sort_index()
    return out


def draw_motion_bands(ax: Axes, results, parameter: str) -> int:
    """Shade the motion classes (``pendsweep.analysis.classify``) behind a bifurcation diagram; return the strips drawn.

    The first branch (continue up, else whatever comes first) shades the full
    height, with the class written in each band; every branch also gets a
    thin strip along the bottom, so hysteresis and coexisting attractors
    (strips of different colour at one value, or ``mixed`` multistarts) show.
    """
    strips = {}
    for df, meta in results:
        strips.update(point_motions(df, branch_label(df, meta), parameter))
    names = sorted(strips, key=lambda b: list(BRANCH_STYLE).index(b) if b in BRANCH_STYLE else 99)
    transform = ax.get_xaxis_transform()
    span = max(float(m.index.max() - m.index.min()) for m in strips.values()) or 1.0
    families: set[str] = set()
    for row, branch in enumerate(names):
        motions = strips[branch]
        values = motions.index.to_numpy(dtype=float)
        half = np.diff(values).min() / 2 if values.size > 1 else 0.5
        edges = np.concatenate([[values[0] - half], (values[1:] + values[:-1]) / 2, [values[-1] + half]])
        labels = motions.to_numpy()
        start = 0
        for k in range(1, labels.size + 1):
            if k < labels.size and labels[k] == labels[start]:
                continue
            family = labels[start].split("-")[0] if labels[start].startswith("periodic") else labels[start]
            colour = MOTION_COLOURS.get(family, "white")
            lo, hi = edges[start], edges[k]
            ax.fill_between(
                [lo, hi], 0.01 + 0.03 * row, 0.035 + 0.03 * row, color=colour, transform=transform, linewidth=0
            )
            families.add(family)
            if row == 0:
                ax.axvspan(lo, hi, color=colour, alpha=0.15, linewidth=0, zorder=0)
                if hi - lo > 0.04 * span:  # name only the bands wide enough to read
                    ax.text(
                        (lo + hi) / 2,
                        0.98,
                        labels[start].replace("periodic-", "period-"),
                        transform=transform,
                        ha="center",
                        va="top",
                        fontsize=6,
                        rotation=90,
                        clip_on=True,
                    )
            start = k
        ax.text(edges[-1], 0.022 + 0.03 * row, f" {branch}", transform=transform, fontsize=6, va="center")
    handles = [Patch(color=MOTION_COLOURS[f], label=f) for f in MOTION_COLOURS if f in families]
    # Outside the axes, right and below the branches' legend: inside, it covered points (issue 24).
    legend = ax.legend(
        handles=handles, loc="lower left", bbox_to_anchor=(1.01, 0.0), fontsize=6, title="motion", title_fontsize=6
    )
    ax.add_artist(legend)
    return len(names)
