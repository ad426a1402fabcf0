"""Continuation branches drawn over bifurcation diagrams (``pendsweep plot``, ``continue --plot``).

Each branch point stores only its section; the plotted observable (the
same per-period quantities as a sweep's records: ``theta_peak``,
``theta_absmax``, ``theta_sec``, ``y_absmax``) is recomputed by integrating
the orbit once over its ``k`` periods with the configuration stored in the
document. A period-``k`` branch gives ``k`` curves (one per forcing period
of the orbit), as a sweep gives ``k`` dots per value. Stable stretches are
solid, unstable ones dashed; bifurcations are marked on their branch.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes

from ..analysis.continuation.problem import BRANCH_POINT, FOLD, NEIMARK_SACKER, PERIOD_DOUBLING
from ..analysis.continuation.run import read_json, stored_problem
from ..analysis.continuation.shooting import PendulumShooting
from ..errors import ConfigError
from ..kernels import RECORD_COLUMNS
from ..model.params import PARAM_SPECS

#: Colour per branch period (forcing periods).
PERIOD_COLOURS = {1: "black", 2: "tab:red", 4: "tab:green", 8: "tab:purple"}
#: Marker per bifurcation type.
BIFURCATION_MARKERS = {
    PERIOD_DOUBLING: dict(marker="o", facecolors="none", edgecolors="tab:blue", s=45, label="period doubling"),
    FOLD: dict(marker="s", facecolors="none", edgecolors="tab:brown", s=45, label="fold"),
    NEIMARK_SACKER: dict(marker="D", facecolors="none", edgecolors="tab:pink", s=45, label="Neimark-Sacker"),
    BRANCH_POINT: dict(marker="v", facecolors="none", edgecolors="tab:olive", s=45, label="branch point (+1, no fold)"),
}


def branch_observables(doc: dict[str, Any], observable: str) -> list[np.ndarray]:
    """Per branch, ``observable`` of every point and orbit period, shape ``(points, k)``.

    The orbit through each stored point is integrated over its ``k`` periods
    with the document's model, step and damping smoothing (the loop's from
    its whole stored ``state``, with the document's backend options).
    """
    column = RECORD_COLUMNS.index(observable)
    out = []
    for branch in doc["branches"]:
        problem = stored_problem(doc, branch["period"])
        key = "section" if isinstance(problem, PendulumShooting) else "state"
        values = np.full((len(branch["points"]), branch["period"]), np.nan)
        for i, pt in enumerate(branch["points"]):
            records = problem.evaluate(np.array(pt[key]), pt["value"], tangent=False).info.records
            values[i] = records[:, column]
        out.append(values)
    return out


def _segment_runs(max_multipliers: np.ndarray) -> list[tuple[int, int, bool]]:
    """``(first point, last point, stable)`` of the stretches of equal stability along a branch.

    A segment between neighbouring points is stable when the mean of their
    ``log max|mu|`` is negative, so a bifurcation point (``|mu| = 1``) joins
    the stretch on its stable side rather than forming a stretch of its own.
    """
    logs = np.log(max_multipliers)
    if logs.size < 2:
        return []
    flags = (logs[:-1] + logs[1:]) < 0.0
    runs, start = [], 0
    for k in range(1, flags.size + 1):
        if k == flags.size or flags[k] != flags[start]:
            runs.append((start, k, bool(flags[start])))
            start = k
    return runs


#: Largest change of a plotted angle [rad] between neighbouring branch points that is drawn as a line.
#: Steps are at most 0.05 rad in the section, so larger jumps are the wrapped angle of a rotating orbit
#: passing +-pi, or the signed peak of a swing changing sign: the line is broken there.
ANGLE_JUMP = 0.5


def _broken(lam: np.ndarray, values: np.ndarray, observable: str) -> tuple[np.ndarray, np.ndarray]:
    """``(lam, values)`` with a NaN inserted after every angle jump larger than :data:`ANGLE_JUMP`."""
    if not observable.startswith("theta"):
        return lam, values
    jumps = np.flatnonzero(np.abs(np.diff(values)) > ANGLE_JUMP) + 1
    return np.insert(lam.astype(float), jumps, np.nan), np.insert(values.astype(float), jumps, np.nan)


def draw_continuation(ax: Axes, doc: dict[str, Any], observable: str = "theta_peak") -> None:
    """Draw the branches and bifurcations of continuation document ``doc`` on ``ax``."""
    if observable not in RECORD_COLUMNS:
        raise ConfigError(f"unknown observable {observable!r}; choose from {', '.join(RECORD_COLUMNS)}")
    observed = branch_observables(doc, observable)
    labelled = set(ax.get_legend_handles_labels()[1])  # one legend entry per kind over several documents
    for branch, values in zip(doc["branches"], observed):
        if not branch["points"]:
            continue
        lam = np.array([p["value"] for p in branch["points"]])
        colour = PERIOD_COLOURS.get(branch["period"], "tab:gray")
        for first, last, stable in _segment_runs(np.array([p["max_multiplier"] for p in branch["points"]])):
            label = f"period-{branch['period']} orbit, {'stable' if stable else 'unstable'}"
            for j in range(values.shape[1]):
                ax.plot(
                    *_broken(lam[first : last + 1], values[first : last + 1, j], observable),
                    color=colour,
                    lw=1.2 if stable else 0.9,
                    ls="-" if stable else "--",
                    label=None if label in labelled else label,
                    zorder=3,
                )
                labelled.add(label)
    for bif in doc["bifurcations"]:
        branch = doc["branches"][bif["branch"]]
        lam = np.array([p["value"] for p in branch["points"]])
        i = int(np.argmin(np.abs(lam - bif["value"])))
        style = dict(BIFURCATION_MARKERS[bif["type"]])
        label = style.pop("label")
        ys = observed[bif["branch"]][i]
        # Not clipped: a bifurcation on the axes' edge (e.g. at the interval's end) stays whole.
        ax.scatter(
            np.full(ys.size, bif["value"]),
            ys,
            label=None if label in labelled else label,
            zorder=4,
            linewidths=1.2,
            clip_on=False,
            **style,
        )
        labelled.add(label)


def plot_any(paths: Sequence[Path], output: Path, observable: str = "theta_peak", title: str | None = None) -> Path:
    """Bifurcation diagram of sweep results (``.parquet``) with continuation documents (``.json``) on top.

    With sweeps, :func:`pendsweep.figures.plotting.plot_files` draws them and the
    branches are added on the same axes; continuation documents alone get
    their own axes.
    """
    from .plotting import plot_files

    sweeps = [Path(p) for p in paths if Path(p).suffix != ".json"]
    docs = [read_json(Path(p)) for p in paths if Path(p).suffix == ".json"]
    parameters = {d["parameter"] for d in docs}
    if sweeps:
        from ..engine.results import read_metadata

        parameters |= {read_metadata(p)["config"]["parameter"] for p in sweeps}
    if len(parameters) > 1:
        raise ConfigError(f"cannot overlay results in different parameters: {', '.join(sorted(parameters))}")
    overlays = [lambda ax, d=d: _overlay(ax, d, observable) for d in docs]
    if sweeps:
        return plot_files(sweeps, output, observable, title, overlays=overlays)
    return plot_continuation(docs, output, observable, title)


def _overlay(ax: Axes, doc: dict[str, Any], observable: str) -> None:
    draw_continuation(ax, doc, observable)
    ax.legend(loc="upper left", fontsize=7, markerscale=1.5)


def wrapped_title(title: str, width: int) -> str:
    """``title`` broken into lines of at most ``width`` characters (a long title is not cut off at the right)."""
    import textwrap

    return "\n".join(textwrap.wrap(title, width)) or title


def plot_continuation(
    docs: Sequence[dict[str, Any]], output: Path, observable: str = "theta_peak", title: str | None = None
) -> Path:
    """Continuation documents alone (no sweep) into ``output`` (PNG/PDF/SVG)."""
    output = Path(output)
    if output.suffix.lower() not in {".png", ".pdf", ".svg"}:
        raise ConfigError(f"plot file {str(output)!r} must end in .png, .pdf or .svg")
    from ..canvas import new_figure

    fig = new_figure((7.5, 4.5))
    ax = fig.subplots()
    for doc in docs:
        draw_continuation(ax, doc, observable)
    parameter = docs[0]["parameter"]
    spec = PARAM_SPECS.get(parameter)
    ax.set_xlabel(f"{parameter} [{spec.unit}]  ({spec.doc})" if spec else f"{parameter} [{docs[0]['unit']}]")
    ax.set_ylabel(f"{observable} [{'m' if observable.startswith('y') else 'rad'}]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=7)
    if title is None:
        cfg = docs[0]["config"]
        fixed = {k: v for k, v in cfg["model"].items() if k in ("alpha", "fe", "M", "b1", "b3") and k != parameter}
        title = "continuation, " + ", ".join(f"{k} = {v:g} {PARAM_SPECS[k].unit}" for k, v in fixed.items())
        title += f", eps = {cfg['eps']:g} rad/s"
        if cfg.get("backend", "emulated") != "emulated":
            opts = cfg["backend_options"]
            title += (
                f"; hybrid loop: {opts['actuator']}, transport delay {1e3 * opts['transport_delay']:g} ms, "
                f"prediction order {opts['predictor_order']}"
            )
    ax.set_title(wrapped_title(title, 90), fontsize=9)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=150)
    return output
