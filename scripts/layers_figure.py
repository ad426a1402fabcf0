"""Draw pendsweep's layers and the imports between them, read from the code: docs/img/layers.png.

The layers are the ``layers`` contract of ``pyproject.toml`` (what
``lint-imports`` checks); the arrows are the imports grimp finds between
the packages (lazy ones included), labelled with how many module pairs
import each other. Run ``make architecture`` (or ``python
scripts/layers_figure.py [OUT]``) after moving modules.
"""

from __future__ import annotations

import sys
import textwrap
import tomllib
from pathlib import Path

import grimp
import numpy as np
from matplotlib.patches import FancyBboxPatch

from pendsweep.canvas import new_figure

ROOT = Path(__file__).resolve().parents[1]


def layers() -> list[list[str]]:
    """The layers contract, top first, each a list of sibling packages (short names)."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    spec = next(c for c in config if c["type"] == "layers")["layers"]
    return [[name.strip().removeprefix("pendsweep.") for name in row.replace(":", "|").split("|")] for row in spec]


def package_edges(names: list[str]) -> dict[tuple[str, str], int]:
    """(importer, imported) package -> number of module-level import pairs between them."""
    graph = grimp.build_graph("pendsweep")

    def package(module: str) -> str | None:
        short = module.removeprefix("pendsweep.")
        return next((n for n in names if short == n or short.startswith(n + ".")), None)

    counts: dict[tuple[str, str], int] = {}
    for module in graph.modules:
        for imported in graph.find_modules_directly_imported_by(module):
            a, b = package(module), package(imported)
            if a and b and a != b:
                counts[(a, b)] = counts.get((a, b), 0) + 1
    return counts


def contents(name: str) -> str:
    """What a package holds, as its modules' and sub-packages' short names."""
    path = ROOT / "src" / "pendsweep" / name
    if not path.is_dir():
        return f"{name}.py"
    items = sorted(p.stem for p in path.iterdir() if (p.suffix == ".py" and p.stem != "__init__") or
                   (p.is_dir() and (p / "__init__.py").exists()))  # fmt: skip
    return ", ".join(i + ("/" if (path / i).is_dir() else "") for i in items if i != "__main__")


def draw(out: Path) -> None:
    rows = layers()
    names = [n for row in rows for n in row]
    edges = package_edges(names)
    fig = new_figure((13.0, 6.4), layout=None)
    left = fig.add_axes((0.01, 0.02, 0.55, 0.93))
    left.set_xlim(0, 10)
    left.set_ylim(-0.6, len(rows) - 0.4)
    left.axis("off")
    left.set_title("layers, top to bottom: a package imports only those below it", fontsize=10, loc="left")
    for level, row in enumerate(rows):
        y = len(rows) - 1 - level
        width = 8.6 / len(row)
        left.text(0.0, y, f"{len(rows) - 1 - level}", ha="left", va="center", fontsize=9, color="0.4")
        for i, name in enumerate(row):
            x0 = 0.9 + width * i
            left.add_patch(FancyBboxPatch((x0, y - 0.4), 0.96 * width, 0.8, boxstyle="round,pad=0.01",
                                          fc="#e8f0fb" if level % 2 else "#f3f3f3", ec="0.35", lw=0.8))  # fmt: skip
            left.text(x0 + 0.08, y + 0.2, name, ha="left", va="center", fontsize=9, weight="bold", family="monospace")
            text = contents(name)
            chars = int(15 * width)
            lines = textwrap.wrap(text, chars)
            wrapped = "\n".join(lines[:2]) + (" ..." if len(lines) > 2 else "")
            left.text(x0 + 0.08, y - 0.12, wrapped, ha="left", va="center", fontsize=6.2, color="0.25")
    right = fig.add_axes((0.64, 0.14, 0.34, 0.72))
    n = len(names)
    matrix = np.zeros((n, n))
    for (a, b), count in edges.items():
        matrix[names.index(a), names.index(b)] = count
    right.imshow(np.where(matrix > 0, np.log10(matrix + 1), np.nan), cmap="Blues", vmin=0, vmax=2.2)
    for i in range(n):
        for j in range(n):
            if matrix[i, j]:
                bad = j <= i and names[j] not in _siblings_below(rows, names[i])
                right.text(j, i, f"{int(matrix[i, j])}", ha="center", va="center", fontsize=6.5,
                           color="tab:red" if bad else "black")  # fmt: skip
    right.set_xticks(range(n), names, rotation=90, fontsize=7, family="monospace")
    right.set_yticks(range(n), names, fontsize=7, family="monospace")
    right.set_xlabel("imported", fontsize=8)
    right.set_ylabel("importer", fontsize=8)
    right.set_title(f"imports between packages, read from the code\n({sum(edges.values())} module pairs; "
                    "all right of the diagonal: downward)", fontsize=8)  # fmt: skip
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130)
    upward = [(a, b) for (a, b) in edges if b not in _siblings_below(rows, a)]
    print(f"{out}: {len(rows)} layers, {len(edges)} package edges, {len(upward)} upward or sideways: {upward}")


def _siblings_below(rows: list[list[str]], name: str) -> set[str]:
    """The packages in the layers below ``name``'s."""
    level = next(i for i, row in enumerate(rows) if name in row)
    return {n for row in rows[level + 1 :] for n in row}


if __name__ == "__main__":
    draw(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "img" / "layers.png")
