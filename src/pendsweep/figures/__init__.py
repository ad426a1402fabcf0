"""Figure registry: ``pendsweep figures [NAME ...]`` and ``make figures``.

A figure is a function ``f(outdir: Path, quick: bool) -> list[Path]``
registered with :func:`figure`. ``quick`` shrinks the work for smoke tests.
Modules that define figures are imported at the bottom of this file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

FigureFn = Callable[[Path, bool], list[Path]]
FIGURES: dict[str, FigureFn] = {}


def figure(name: str) -> Callable[[FigureFn], FigureFn]:
    """Decorator registering a figure under ``name``."""

    def deco(fn: FigureFn) -> FigureFn:
        FIGURES[name] = fn
        return fn

    return deco


def make_figures(names: list[str] | None, outdir: Path, quick: bool = False) -> list[Path]:
    """Draw the named figures (all when ``names`` is empty) into ``outdir``."""
    from ..errors import ConfigError

    names = names or list(FIGURES)
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise ConfigError(f"unknown figure(s) {', '.join(unknown)}; choose from {', '.join(FIGURES)}")
    outdir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for name in names:
        written += FIGURES[name](outdir, quick)
    return written

from . import core  # noqa: E402,F401  (registers figures)
from . import hopf  # noqa: E402,F401  (Fig. 10 and the coexistence figure)
from . import hybrid  # noqa: E402,F401  (registers the hybrid-test figures)
from . import stability  # noqa: E402,F401  (registers the stability figures)
from . import measured  # noqa: E402,F401  (free-swing damping, Fig. 2 procedure)
from . import continuation  # noqa: E402,F401  (Fig. 11 with continuation branches, issue 15)
from . import basins  # noqa: E402,F401  (basin maps, basin fractions, two-parameter maps)
