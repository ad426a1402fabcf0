"""The figure registry: :func:`figure` registers a figure function under a name; :func:`make_figures` draws them."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

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
