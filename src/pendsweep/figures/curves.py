"""Figures of two-parameter bifurcation curves (``pendsweep curve --plot``) and the delay-tolerance curve.

A curve is drawn in its parameter plane, or over a ``pendsweep map`` of the
same two parameters (the map's motion classes as an image, its semi-trivial
Hopf boundary by Floquet theory, Fig. 10, as a line): the curves must lie on
the image's class boundaries. Codimension-two points are marked; legends sit
below their panel, never over another (``tests/test_figures.py`` checks).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.patches import Patch

from ..analysis.continuation.run import parameter_unit
from ..canvas import legend_below, new_figure
from ..engine.results import read_results
from ..errors import ConfigError, RunFailure
from ..studies.maps import MapConfig, hopf_boundaries
from .basins import _OUTLINED, _colour, draw_map_classes
from .registry import figure

#: Line style per curve kind.
CURVE_STYLES = {
    "period-doubling": dict(color="tab:red", lw=1.6),
    "fold": dict(color="black", lw=1.6, ls="--"),
    "neimark-sacker": dict(color="tab:purple", lw=1.6, ls="-."),
}
#: Marker per codimension-two event (turns are not marked: they are visible).
EVENT_MARKERS = {
    "cusp": "^",
    "degenerate period doubling": "o",
    "1:1 resonance": "s",
    "1:2 resonance": "D",
    "1:3 resonance": "P",
    "1:4 resonance": "X",
    "fold-flip": "v",
    "fold-Neimark-Sacker": "<",
    "flip-Neimark-Sacker": ">",
    "double Neimark-Sacker": "*",
}


def _label(parameter: str, unit: str) -> str:
    return f"{parameter} [{unit}]"


def check_overlays(plane: tuple[str, str], overlays: list[Path]) -> None:
    """Refuse, before a curve is computed, overlays that are not curve or map results in the plane ``plane``."""
    from ..engine.results import read_metadata

    for path in overlays:
        meta = read_metadata(path)
        cfg = meta.get("config", {})
        kind = meta.get("kind")
        if kind == "map":
            axes = {cfg.get("x"), cfg.get("y")}
        elif kind == "curve":
            axes = {cfg.get("first"), cfg.get("second")}
        else:
            raise ConfigError(f"--overlay {str(path)!r} is a {kind!r} file; give curve or map results")
        if axes != set(plane):
            raise ConfigError(
                f"--overlay {str(path)!r} is over ({', '.join(sorted(map(str, axes)))}), the curve over ({plane[0]}, {plane[1]})"
            )


def plot_curves(paths: list[Path], output: Path) -> Path:
    """Curves (``kind = "curve"`` files) over at most one map (``kind = "map"``).

    The second parameter runs along x and the first along y (f_e against alpha, say), or the map's own
    axes when there is one.
    """
    curves, maps = [], []
    for path in paths:
        rows, meta = read_results(path)
        (maps if meta.get("kind") == "map" else curves).append((rows, meta, path))
        if meta.get("kind") not in ("map", "curve"):
            raise ConfigError(f"{str(path)!r} is a {meta.get('kind')!r} file; give curve or map results")
    if len(maps) > 1:
        raise ConfigError("give at most one map to draw the curves over")
    first, second = curves[0][1]["config"]["first"], curves[0][1]["config"]["second"]
    check_overlays((first, second), [path for _, _, path in curves[1:] + maps])
    x, y = second, first
    fig = new_figure((6.4, 5.6))
    ax = fig.subplots()
    handles = []
    if maps:
        rows, meta, path = maps[0]
        config = MapConfig(**{k: v for k, v in meta["config"].items()})
        if {config.x, config.y} != {first, second}:
            raise ConfigError(
                f"map {str(path)!r} is over ({config.x}, {config.y}), the curves over ({first}, {second})"
            )
        x, y = config.x, config.y
        handles += _draw_map(ax, rows, config)
    units = {name: parameter_unit(name) for name in (first, second)}
    drawn_events: set[str] = set()
    for rows, meta, _ in curves:
        kind = meta["config"]["kind"]
        ordered = rows.sort_values("point")
        label = f"{kind} curve" + (
            " (hybrid loop)" if meta["config"]["continuation"].get("backend") == "substructured" else ""
        )
        style = CURVE_STYLES[kind] | ({"color": "tab:orange"} if "hybrid" in label else {})
        (line,) = ax.plot(ordered[x], ordered[y], label=label, **style)
        handles.append(line)
        for event, group in rows[rows["event"].isin(EVENT_MARKERS)].groupby("event"):
            mark = ax.scatter(group[x], group[y], marker=EVENT_MARKERS[event], s=50, facecolors="none",
                              edgecolors="black", zorder=5, label=event if event not in drawn_events else None)  # fmt: skip
            if event not in drawn_events:
                handles.append(mark)
                drawn_events.add(event)
    ax.set_xlabel(_label(x, units[x]))
    ax.set_ylabel(_label(y, units[y]))
    ax.grid(alpha=0.3)
    legend_below(ax, handles=handles, ncol=2)
    kinds = ", ".join(sorted({m["config"]["kind"] for _, m, _ in curves}))
    ax.set_title(f"{kinds} curve(s) in ({first}, {second})" + (", over the map" if maps else ""), fontsize=10)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=150)
    return output


def _draw_map(ax, rows: pd.DataFrame, config: MapConfig) -> list:
    """The map's motion classes as an image and its Floquet Hopf boundary; returns legend handles."""
    present, extent = draw_map_classes(ax, rows, config, alpha=0.6)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    handles = [Patch(color=_colour(c), alpha=0.6, label=f"map: {c}") for c in present]
    boundaries = hopf_boundaries(config)
    if boundaries is not None:
        other = [c for c in boundaries.columns if c not in ("analytic", "floquet")][0]
        xy = (
            (boundaries["floquet"], boundaries[other])
            if config.x == "alpha"
            else (boundaries[other], boundaries["floquet"])
        )
        (line,) = ax.plot(*xy, color="white", lw=1.5, zorder=2, path_effects=_OUTLINED,
                          label="Hopf boundary (Floquet, Fig. 10)")  # fmt: skip
        handles.append(line)
    return handles


def plot_tolerance(path: Path, output: Path) -> Path:
    """The bifurcation's relative shift against the effective delay, per prediction order, with the tolerance band."""
    rows, meta = read_results(path)
    if meta.get("kind") != "tolerance":
        raise ConfigError(f"{str(path)!r} is not a tolerance result")
    if rows.empty:
        raise RunFailure(f"{str(path)!r} holds no point: no order found its bifurcation in the loop (see its ends)")
    cfg = meta["config"]
    within = cfg["within"]
    fig = new_figure((6.4, 4.8))
    ax = fig.subplots()
    marked = limited = False
    for order, group in rows.groupby("order"):
        name = "no prediction" if order < 0 else f"prediction order {order}"
        group = group.sort_values("point")
        stable = group["loop_stable"].to_numpy(dtype=bool)
        delay, shift = 1e3 * group["effective_delay"].to_numpy(), 100 * group["shift"].to_numpy()
        first_unstable = int(np.argmin(stable)) if not stable.all() else len(stable)
        (line,) = ax.plot(delay[:first_unstable], shift[:first_unstable], lw=1.5, label=name)
        if first_unstable < len(stable):  # the loop itself unstable: no test could hold it on this orbit
            ax.plot(delay[first_unstable - 1 :], shift[first_unstable - 1 :], lw=1.0, ls=":", color=line.get_color())
            ax.plot([delay[first_unstable]], [shift[first_unstable]], "x", ms=8, mew=2, color=line.get_color(),
                    label=None if marked else "the loop itself unstable from here")  # fmt: skip
            marked = True
        limit = meta["limits"].get(str(int(order)))
        if limit is not None and limit < cfg["delays"][1] - 1e-12:
            at = float(np.interp(limit, group["transport_delay"], group["effective_delay"]))
            shifted = float(np.interp(limit, group["transport_delay"], group["shift"]))
            ax.plot([1e3 * at], [100 * shifted], "o", color=line.get_color(), mfc="none",
                    label=None if limited else f"within {100 * within:g} % on a stable loop up to here")  # fmt: skip
            limited = True
    ax.axhspan(-100 * within, 100 * within, color="tab:green", alpha=0.12, label=f"within {100 * within:g} %")
    ax.axhline(0.0, color="black", lw=0.6)
    kind = cfg["bifurcation"]["type"]
    unit = parameter_unit(cfg["continuation"]["parameter"])
    ax.set_xlabel("total effective delay at the forcing frequency [ms]")
    ax.set_ylabel(f"shift of the {kind} [%]")
    ax.set_title(
        f"hybrid loop: {kind} at {cfg['continuation']['parameter']} = {meta['reference']:.5g} {unit} (emulated), "
        "against the rig's delay",
        fontsize=9,
    )
    ax.grid(alpha=0.3)
    legend_below(ax, ncol=2)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=150)
    return output


# -- registered figures (make figures) ------------------------------------------------------
def _pd_continuation(outdir: Path) -> Path:
    """The emulated semi-trivial branch at fe = 2.5 Hz (b1 = b3 = 0) with its period doubling, as a file."""
    from ..analysis.continuation.run import ContinuationConfig, run_continuation, write_json

    path = outdir / "curve-start.json"
    config = ContinuationConfig("alpha", 10.0, 25.0, {"fe": 2.5, "b1": 0.0, "b3": 0.0}, max_period=1)
    write_json(run_continuation(config), path)
    return path


@figure("curve_pd_map")
def curve_pd_map(outdir: Path, quick: bool) -> list[Path]:
    """The semi-trivial solution's period-doubling curve in (alpha, fe) over a map of the same plane (Fig. 10's range)."""
    from ..analysis.continuation.curve_run import config_from_file, run_curve
    from ..model.params import TABLE_IV
    from ..studies.hopf import fe_for_omega_hat
    from ..studies.maps import MapConfig, run_map

    smooth = {"b1": 0.0, "b3": 0.0}
    fe_range = tuple(fe_for_omega_hat(TABLE_IV.replace(**smooth), w) for w in (0.88, 1.12))
    config = config_from_file(_pd_continuation(outdir), 0, second="fe", start=fe_range[0], stop=fe_range[1],
                              first_limits=(0.0, 40.0))  # fmt: skip
    curve = outdir / "curve-pd.parquet"
    curve.unlink(missing_ok=True)
    run_curve(config, curve)
    n = 24 if quick else 120
    grid = MapConfig("alpha", tuple(np.linspace(0.0, 40.0, n)), "fe", tuple(np.linspace(*fe_range, n)), model=smooth,
                     max_periods=100 if quick else 600)  # fmt: skip
    map_path = outdir / "curve-map.parquet"
    run_map(grid, map_path, overwrite=True, return_rows=False)
    return [plot_curves([curve, map_path], outdir / f"curve_pd_map{'-quick' if quick else ''}.png")]


@figure("tolerance_pd")
def tolerance_pd(outdir: Path, quick: bool) -> list[Path]:
    """The hybrid loop's period doubling against the rig's delay, per prediction order (the delay-tolerance figure)."""
    from ..analysis.continuation.tolerance import ToleranceConfig, run_tolerance

    config = ToleranceConfig.from_file(
        _pd_continuation(outdir), 0, delays=(0.0, 0.03), orders=(1, 2) if quick else (-1, 0, 1, 2, 3),
        delay_step=0.005 if quick else 2.5e-4,
    )  # fmt: skip
    out = outdir / "tolerance-pd.parquet"
    run_tolerance(config, out, resume=True)
    return [plot_tolerance(out, outdir / f"tolerance_pd{'-quick' if quick else ''}.png")]
