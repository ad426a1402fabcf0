"""Figures show their data: no legend box covers a data point, on any figure a command draws (issue 24).

Every figure a command saves is inspected just before it is written: for
each legend, the data drawn in the figure (line vertices, scatter points,
image pixels) is transformed to display coordinates and none may fall inside
the legend's box. Reference lines of two points (axhline, axvline) are not data.
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.legend import Legend

from pendsweep.cli import main


def _data_points(fig: Figure) -> np.ndarray:
    """Display coordinates of every drawn data point of ``fig``, shape (n, 2)."""
    points = [np.empty((0, 2))]
    for ax in fig.axes:
        box = ax.get_window_extent()
        for line in ax.get_lines():
            xy = np.asarray(line.get_xydata(), dtype=float)
            if len(xy) <= 2 or not line.get_visible():
                continue
            xy = xy[np.all(np.isfinite(xy), axis=1)]
            shown = line.get_transform().transform(xy)
            points.append(
                shown[
                    (shown[:, 0] >= box.x0)
                    & (shown[:, 0] <= box.x1)
                    & (shown[:, 1] >= box.y0)
                    & (shown[:, 1] <= box.y1)
                ]
            )
        for collection in ax.collections:
            offsets = np.asarray(collection.get_offsets(), dtype=float)
            if offsets.size:
                points.append(collection.get_offset_transform().transform(offsets))
        for image in ax.get_images():
            if isinstance(image, AxesImage):
                extent = image.get_window_extent()
                xs = np.linspace(extent.x0, extent.x1, 20)
                ys = np.linspace(extent.y0, extent.y1, 20)
                points.append(np.array([(x, y) for x in xs for y in ys]))
    return np.concatenate(points)


def covered(fig: Figure) -> list[str]:
    """Legends of ``fig`` that cover data: a description of each."""
    fig.canvas.draw()
    points = _data_points(fig)
    found = []
    # Every legend, also those kept with add_artist (a second legend, e.g. the motion classes).
    legends = [c for ax in fig.axes for c in ax.get_children() if isinstance(c, Legend)] + list(fig.legends)
    for legend in legends:
        box = legend.get_window_extent().padded(-1)
        inside = (points[:, 0] > box.x0) & (points[:, 0] < box.x1) & (points[:, 1] > box.y0) & (points[:, 1] < box.y1)
        if inside.any():
            texts = [t.get_text() for t in legend.get_texts()][:2]
            found.append(f"legend {texts} covers {int(inside.sum())} data points")
    return found


@pytest.fixture
def inspected(monkeypatch):
    """Every figure saved while the fixture is active, with the legends that cover its data."""
    seen: list[tuple[str, list[str]]] = []
    original = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        seen.append((str(fname), covered(self)))
        return original(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return seen


COMMANDS = {
    "sweep --plot": ["alpha", "--from", "30", "--to", "34", "--step", "1", "--mode", "fresh", "--plot", "a.png", "-o", "a.parquet"],
    "sweep --plot (Fig. 11(a), both directions)": ["alpha", "--from", "0", "--to", "45", "--direction", "both", "--plot", "w.png", "-o", "w.parquet"],
    "sweep --plot (fe)": ["fe", "--from", "2.0", "--to", "3.0", "--step", "0.02", "--plot", "e.png", "-o", "e.parquet"],
    "basins --plot (one value)": ["basins", "--alpha", "40", "--grid", "10x10", "--max-periods", "60", "--plot", "b.png", "-o", "b.parquet"],
    "basins --plot (a range)": ["basins", "alpha", "--from", "38", "--to", "40", "--step", "1", "--samples", "30", "--max-periods", "60", "--plot", "c.png", "-o", "c.parquet"],
    "map --plot": ["map", "alpha", "fe", "--alpha", "10:30:4", "--fe", "2.2:2.6:4", "--max-periods", "60", "--plot", "m.png", "-o", "m.parquet"],
    "margin --plot": ["margin", "--plot", "margin.png"],
    "plot": ["plot", "{sweep}", "-o", "p.png"],
    "sync": ["{trace}", "sync", "t.parquet", "-o", "s.png"],
    "fit-damping --plot": ["{record}", "fit-damping", "r.csv", "--plot", "f.png"],
    "diagnose --report": ["{record}", "diagnose", "r.csv", "--report", "rep"],
    "diagnose --report (part by part)": ["{substructured}", "diagnose", "s.parquet", "--report", "rep2"],
    "figures (quick)": ["figures", "fig8", "fig9", "fig11a", "fig10a", "fig5_margin", "fig6_chart", "fig9_hybrid",
                        "fig12_sync", "free_swing_damping", "fig11b", "fig10b", "coexistence", "fig11_hybrid",
                        "stability_validation", "basin40", "basin_fractions", "map_alpha_fe", "fig11_continuation",
                        "--quick", "-o", "figs"],
    "continue --plot": ["continue", "alpha", "--from", "30", "--to", "31", "--max-points", "4", "-o", "k.json", "--plot", "k.png"],
}  # fmt: skip


@pytest.mark.parametrize("name", list(COMMANDS))
def test_no_legend_covers_data(name, inspected, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = COMMANDS[name]
    inputs = {  # the files a command reads, made first
        "{sweep}": COMMANDS["sweep --plot"],
        "{trace}": ["trace", "t.parquet", "--periods", "6", "--transient-periods", "20"],
        "{record}": ["synth", "r.csv", "--duration", "15", "--effect", "viscous_damping=2e-4"],
        "{substructured}": ["synth", "s.parquet", "--kind", "substructured", "--duration", "6"],
    }
    for marker, make in inputs.items():
        if marker in args:
            assert CliRunner().invoke(main, make).exit_code == 0
            args = [a.replace(marker, "a.parquet") for a in args if a != marker or marker == "{sweep}"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert inspected, "the command saved no figure"
    bad = [(path, found) for path, found in inspected if found]
    assert not bad, bad


def test_the_check_sees_a_legend_over_data():
    """The check is evidence only if it fails on a legend drawn over a curve."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure()
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    x = np.linspace(0, 1, 200)
    ax.plot(x, np.ones_like(x), label="flat")
    ax.legend(loc="center")
    assert covered(fig)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1))
    assert not covered(fig)
