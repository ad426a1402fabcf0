"""Figures show their data readably, on any figure a command draws (issues 24 and 31).

Every figure a command saves is inspected just before it is written:

* no legend box covers a data point: the data drawn in the figure (line
  vertices, scatter points, image pixels) is transformed to display
  coordinates and none may fall inside a legend's box (reference lines of two
  points, axhline and axvline, are not data);
* no two tick labels of an axis run into each other: their boxes keep
  :data:`TICK_GAP` pixels apart (``-0.015-0.010`` read as one number);
* a title over a frequency axis names only frequencies that axis shows (a
  PSD titled with a peak at 486.8 Hz over an axis that stops at 20 Hz).
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
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


def over_other_panels(fig: Figure) -> list[str]:
    """Legends of one panel of ``fig`` that reach into another panel (its axes, ticks, labels or title)."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    found = []
    for ax in fig.axes:
        legends = [c for c in ax.get_children() if isinstance(c, Legend)]
        for legend in legends:
            box = legend.get_window_extent(renderer).padded(-1)
            for other in fig.axes:
                if other is ax or not other.get_visible() or other in _colorbars_of(ax, fig):
                    continue
                if box.overlaps(other.get_tightbbox(renderer)):
                    texts = [t.get_text() for t in legend.get_texts()][:2]
                    found.append(f"legend {texts} of {ax.get_title()[:40]!r} reaches into {other.get_title()[:40]!r}")
    return found


def _colorbars_of(ax, fig: Figure) -> list:
    """Colour-bar axes drawn for ``ax`` (a legend beside an image may sit next to its own colour bar)."""
    return [other for other in fig.axes if getattr(other, "_colorbar", None) is not None]


#: Least gap [px] between two tick labels of one axis: about a space at the default size, 120 dpi.
TICK_GAP = 6.0


def crowded_tick_labels(fig: Figure) -> list[str]:
    """Pairs of shown tick labels (major or minor) of one axis of ``fig`` closer than :data:`TICK_GAP`."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    found = []
    for ax in fig.axes:
        if not ax.get_visible() or not ax.axison:
            continue
        box = ax.get_window_extent(renderer)
        for name, axis, low, high in (("x", ax.xaxis, "x0", "x1"), ("y", ax.yaxis, "y0", "y1")):
            shown = []
            for label in axis.get_majorticklabels() + axis.get_minorticklabels():
                if not label.get_visible() or not label.get_text():
                    continue
                extent = label.get_window_extent(renderer)
                centre = 0.5 * (getattr(extent, low) + getattr(extent, high))
                # labels of ticks beyond the view exist but are not drawn
                if getattr(box, low) - 1 <= centre <= getattr(box, high) + 1:
                    shown.append((extent.padded(TICK_GAP / 2), label.get_text()))
            for i, (first, first_text) in enumerate(shown):
                for second, second_text in shown[i + 1 :]:
                    if first.overlaps(second):
                        found.append(f"{ax.get_title()!r}: {name} tick labels {first_text!r} and {second_text!r} touch")
    return found


#: A frequency named in a title: "486.8 Hz", "20 Hz" (of "0-20 Hz").
FREQUENCY = re.compile(r"(\d+(?:\.\d+)?)\s*Hz")


def frequencies_off_axis(fig: Figure) -> list[str]:
    """Frequencies named in the title of a frequency axis of ``fig`` that lie outside its shown range."""
    found = []
    for ax in fig.axes:
        if "frequency" not in ax.get_xlabel() and "[Hz]" not in ax.get_xlabel():
            continue
        low, high = sorted(ax.get_xlim())
        for named in FREQUENCY.findall(ax.get_title()):
            if not low * (1 - 1e-9) <= float(named) <= high * (1 + 1e-9):
                found.append(f"{ax.get_title()!r} names {named} Hz; its axis shows {low:g} to {high:g} Hz")
    return found


@pytest.fixture
def inspected(monkeypatch):
    """Every figure saved while the fixture is active, with what makes it hard to read (legends over data,
    crowded tick labels, frequencies named off the axis)."""
    seen: list[tuple[str, list[str]]] = []
    original = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        problems = covered(self) + over_other_panels(self) + crowded_tick_labels(self) + frequencies_off_axis(self)
        seen.append((str(fname), problems))
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
    "curve --plot --overlay map": ["curve", "{continuation}", "--second", "fe", "--from", "2.4", "--to", "2.6", "--max-points", "8",
                                   "-o", "cv.parquet", "--plot", "cv.png", "--overlay", "{map}"],
    "tolerance --plot": ["tolerance", "{continuation}", "--delay-from", "0.009", "--delay-to", "0.0105", "--delay-step", "0.0005",
                         "--orders", "1", "-o", "tol.parquet", "--plot", "tol.png"],
}  # fmt: skip


@pytest.mark.parametrize("name", list(COMMANDS))
def test_figures_are_readable(name, inspected, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = COMMANDS[name]
    inputs = {  # the files a command reads, made first
        "{sweep}": COMMANDS["sweep --plot"],
        "{trace}": ["trace", "t.parquet", "--periods", "6", "--transient-periods", "20"],
        "{record}": ["synth", "r.csv", "--duration", "15", "--effect", "viscous_damping=2e-4"],
        "{substructured}": ["synth", "s.parquet", "--kind", "substructured", "--duration", "6"],
    }
    made = {  # inputs passed by name: marker -> (the command that makes it, its file)
        "{continuation}": (["continue", "alpha", "--from", "15", "--to", "17", "--set", "b1=0", "--set", "b3=0",
                            "--max-period", "1", "-o", "c.json"], "c.json"),
        "{map}": (["map", "alpha", "fe", "--alpha", "10:30:6", "--fe", "2.4:2.6:6", "--set", "b1=0", "--set", "b3=0",
                   "--max-periods", "60", "-o", "map.parquet"], "map.parquet"),
    }  # fmt: skip
    for marker, make in inputs.items():
        if marker in args:
            assert CliRunner().invoke(main, make).exit_code == 0
            args = [a.replace(marker, "a.parquet") for a in args if a != marker or marker == "{sweep}"]
    for marker, (make, name) in made.items():
        if marker in args:
            assert CliRunner().invoke(main, make).exit_code == 0
            args = [name if a == marker else a for a in args]
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


def test_the_check_sees_a_legend_over_another_panel():
    """The panel check is evidence only if it fails on a legend pushed into the next panel's tick labels."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(figsize=(8, 3))  # no layout engine: nothing makes room for the legend
    FigureCanvasAgg(fig)
    left, right = fig.subplots(1, 2)
    x = np.linspace(0, 1, 50)
    left.plot(x, x, label="a line with a long legend entry")
    right.plot(x, x)
    left.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0))
    assert over_other_panels(fig)
    left.legend(loc="upper left")
    assert not over_other_panels(fig)


def test_the_check_sees_crowded_tick_labels():
    """The tick check is evidence only if it fails on labels in metres that run into each other."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(figsize=(3, 3), dpi=120)
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.plot([-0.02, 0.02], [-0.02, 0.02])
    ax.set_xticks(np.arange(-0.02, 0.021, 0.005))
    assert crowded_tick_labels(fig)
    ax.plot([-20, 20], [-20, 20])  # the same in mm, on round ticks
    ax.set_xticks([-20, -10, 0, 10, 20])
    ax.set_yticks([-20, -10, 0, 10, 20])
    assert not crowded_tick_labels(fig)


def test_the_check_sees_a_frequency_off_the_axis():
    """The title check is evidence only if it fails on the peak of issue 31 over a 0-20 Hz axis."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure()
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.set(xlabel="frequency [Hz]", title="error PSD (peak 486.80 Hz)", xlim=(0, 20))
    assert frequencies_off_axis(fig)
    ax.set_title("error PSD: peak 2.20 Hz (+63 dB) in 0-20 Hz (shaded)")
    assert not frequencies_off_axis(fig)


def test_the_sync_figure_of_a_site_log_names_what_it_shows(inspected, tmp_path, monkeypatch):
    """A site's log (issue 31): motion at 2.2 Hz, LVDT noise and a tone at 486.8 Hz in the error.

    The report's in-band peak is the motion's, the tone is reported apart, and
    the figure's PSD title names the frequencies the report prints, on an axis
    that shows them; tick labels keep apart.
    """
    from pendsweep.figures.hybrid import draw_sync
    from pendsweep.hybrid.sync import analyse

    dt = 1.0 / 1001.0
    t = np.arange(20_000) * dt
    y = 0.018 * np.sin(2 * np.pi * 2.2 * t)
    noise = np.random.default_rng(0).normal(0.0, 2e-5, t.size)
    x = 0.998 * y + noise + 5e-6 * np.sin(2 * np.pi * 486.8 * t)
    report = analyse(pd.DataFrame({"t": t, "y": y, "x_meas": x}))
    assert abs(report.peak.frequency - 2.2) < 0.11 and report.peak.level_db > 20
    assert abs(report.high_peak.frequency - 486.8) < 0.11
    titles: list[str] = []
    inspect_and_save = Figure.savefig

    def keep_titles(self, fname, *args, **kwargs):
        titles.extend(ax.get_title() for ax in self.axes)
        return inspect_and_save(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep_titles)
    draw_sync(pd.DataFrame({"t": t, "y": y, "x_meas": x}), report, tmp_path / "sync.png")
    ((_, found),) = inspected
    assert not found, found
    (psd_title,) = [title for title in titles if "PSD" in title]
    printed = {f"{float(v):.1f}" for line in report.lines() if "PSD" in line for v in FREQUENCY.findall(line)}
    drawn = {f"{float(v):.1f}" for v in FREQUENCY.findall(psd_title)}
    assert {"2.2", "486.8"} <= printed & drawn, (printed, drawn)
