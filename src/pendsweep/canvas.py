"""The figure helpers every layer that draws shares: a figure on its own canvas, legends out of the data.

Figures are drawn on :class:`matplotlib.figure.Figure` objects with an
explicit Agg canvas (:func:`new_figure`), never through pyplot's global
state: importing pendsweep leaves matplotlib's backend alone, so notebooks
and interactive sessions keep theirs. A bottom-layer module (beside
:mod:`pendsweep.errors`): a study's or a diagnosis's own report draws with
it without importing the figures above them.
"""

from __future__ import annotations

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def new_figure(figsize: tuple[float, float], layout: str | None = "constrained") -> Figure:
    """A figure of ``figsize`` inches on its own non-interactive Agg canvas (no pyplot, no backend switch).

    ``fig.savefig`` writes PNG, PDF or SVG by the file's suffix; the figure is
    garbage-collected like any object, nothing to close.
    """
    fig = Figure(figsize=figsize, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def legend_below(ax, **kwargs):
    """A legend under the axes, where it cannot cover data (images, dense branches): centred, in columns."""
    kwargs.setdefault("fontsize", 7)
    kwargs.setdefault("ncol", 3)
    return ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), frameon=False, **kwargs)


def legend_right(ax, **kwargs):
    """A legend right of the axes, for stacked panels (save with ``bbox_inches="tight"`` to keep it)."""
    kwargs.setdefault("fontsize", 7)
    return ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), **kwargs)
