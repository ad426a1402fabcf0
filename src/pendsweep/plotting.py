"""Bifurcation diagrams in the style of Fig. 11."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from .errors import ConfigError  # noqa: E402
from .params import PARAM_SPECS  # noqa: E402
from .results import read_results  # noqa: E402

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
    ax: plt.Axes,
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
    spec = PARAM_SPECS[parameter]
    ax.set_xlabel(f"{parameter} [{spec.unit}]  ({spec.doc})")
    ax.set_ylabel(OBSERVABLES[observable])
    if observable.startswith("theta") and observable != "theta_absmax":
        ax.set_ylim(-np.pi, np.pi)
        ax.set_yticks([-np.pi, -np.pi / 2, 0, np.pi / 2, np.pi], [r"$-\pi$", r"$-\pi/2$", "0", r"$\pi/2$", r"$\pi$"])
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, markerscale=2)


def plot_files(paths: Sequence[Path], output: Path, observable: str = "theta_peak", title: str | None = None) -> Path:
    """Draw the bifurcation diagram of one or more result files into ``output`` (PNG/PDF/SVG)."""
    output = Path(output)
    if output.suffix.lower() not in {".png", ".pdf", ".svg"}:
        raise ConfigError(f"plot file {str(output)!r} must end in .png, .pdf or .svg")
    results = [read_results(Path(p)) for p in paths]
    fig, ax = plt.subplots(figsize=(7.5, 4.5), constrained_layout=True)
    draw_bifurcation(ax, results, observable)
    if title is None:
        cfg = results[0][1]["config"]
        fixed = {k: v for k, v in cfg["model"].items() if k in ("alpha", "fe", "M", "C", "K") and k != cfg["parameter"]}
        title = f"{cfg['backend']} backend, {cfg['mode']} mode; " + ", ".join(
            f"{k} = {v:g} {PARAM_SPECS[k].unit}" for k, v in fixed.items()
        )
    ax.set_title(title, fontsize=9)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=150)
    plt.close(fig)
    return output
