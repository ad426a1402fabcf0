"""Figure registry: ``pendsweep figures [NAME ...]`` and ``make figures``.

A figure is a function ``f(outdir: Path, quick: bool) -> list[Path]``
registered with :func:`figure`. ``quick`` shrinks the work for smoke tests.
Modules that define figures are imported here; the registry itself is :mod:`.registry`.
"""

# Each module registers its figures on import (Figs. 8, 9, 11; Fig. 10; hybrid tests; stability; measured data;
# Fig. 11 with continuation branches; basins and two-parameter maps).
from . import basins, continuation, core, curves, hopf, hybrid, measured, stability  # noqa: F401
from .registry import FIGURES, FigureFn, figure, make_figures

__all__ = ["FIGURES", "FigureFn", "figure", "make_figures"]
