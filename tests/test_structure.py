"""Each piece of physics is written once (issue 10): checks anyone can rerun.

Equivalent shell checks::

    grep -rn "2.0 \\* k2\\|2.0 \\* k2y\\|+ 2.0 \\*" src/pendsweep   # the RK4 weighted sum: _tuple.py only
    grep -rn '"m", "l", "b1"' src/pendsweep                      # parameter order: nowhere by hand
"""

import ast
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "pendsweep"
KERNEL_FILES = sorted((SRC / "kernels").glob("*.py"))
#: Benchmark peers: the scripts a user would write without pendsweep, independent by design
#: (numpy/JAX cannot call numba functions; the naive script must not import the package), and the
#: diagnosis testbench and its servo rig, whose records must share no integration code with the replay (issue 11).
PEERS = [
    "bench/naive_sweep.py",
    "bench/throughput.py",
    "measured/diagnose/testbench.py",
    "measured/diagnose/servo_rig.py",
]
#: The longest a numba kernel function may be (issue 10: "no kernel function over about 80 lines").
MAX_KERNEL_LINES = 80


def _python_files():
    return sorted(SRC.rglob("*.py"))


def test_rk4_weighted_stage_sum_is_written_once():
    # "k1 + 2 k2 + 2 k3 + k4" in any spelling: a "+ 2.0 *" or "+ 2 *" followed by another of them.
    pattern = re.compile(r"\+\s*(2(\.0)?|two)\s*\*\s*[\w\[\]{}.]+\s*\+\s*(2(\.0)?|two)\s*\*")
    hits = [f"{p.relative_to(SRC)}:{i}" for p in _python_files() for i, line in enumerate(p.read_text().splitlines(), 1)
            if pattern.search(line)]  # fmt: skip
    files = sorted({h.split(":")[0] for h in hits})
    # _tuple.py twice (the plain form and the compiled overload's template), and the peers.
    assert files == sorted([*PEERS, "kernels/_tuple.py"]), hits
    assert sum(h.startswith("kernels/_tuple.py") for h in hits) == 2, hits


@pytest.mark.parametrize("rhs", ["eq11_rhs", "model_rhs", "servo_rig_rhs", "pivot_pendulum_rhs", "mathieu_rhs"])
def test_each_right_hand_side_is_defined_once(rhs):
    defs = [p.relative_to(SRC) for p in _python_files() if re.search(rf"^def {rhs}\(", p.read_text(), re.M)]
    assert [str(d) for d in defs] == ["kernels/_rhs.py"]


def test_damping_law_is_written_once():
    law = re.compile(r"b1\s*\*\s*\w+\s*\+\s*b2\s*\*\s*\w+\s*\+\s*b3")
    hits = [str(p.relative_to(SRC)) for p in _python_files() if law.search(p.read_text())]
    # The testbench takes its friction from its own servo rig (no damping law of its own).
    assert sorted(hits) == sorted([*(p for p in PEERS if p != "measured/diagnose/testbench.py"), "kernels/_rhs.py"])


def test_parameter_order_is_never_written_by_hand():
    literal = re.compile(r"""["']m["'],\s*["']l["'],\s*["']b1["']""")
    hits = [str(p.relative_to(SRC)) for p in _python_files() if literal.search(p.read_text())]
    assert hits == ["kernels/_layout.py"]  # looks the indices up by name in params.KERNEL_FIELDS


@pytest.mark.parametrize("path", KERNEL_FILES, ids=lambda p: p.name)
def test_no_kernel_function_is_longer_than_80_lines(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            # Count code lines: the docstring documents the contract and does not count.
            doc = ast.get_docstring(node)
            doc_lines = len(doc.splitlines()) + 2 if doc else 0
            length = node.end_lineno - node.lineno + 1 - doc_lines
            assert length <= MAX_KERNEL_LINES, f"{path.name}:{node.name} has {length} code lines"


# -- imports: no circle between pendsweep's modules --------------------------------------------------------
def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph() -> dict[str, set[str]]:
    """Module -> the pendsweep modules it imports, at any depth of the file (lazy imports count).

    Importing ``a.b.c`` also runs the packages ``a.b`` and ``a``, so each target
    brings its parent packages too, except the root and the importer's own
    ancestors (a package's modules run inside it).
    """
    files = {_module_name(p): p for p in SRC.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                bases = [alias.name for alias in node.names]
                names: list[str] = []
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(anchor + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                bases, names = [base], [alias.name for alias in node.names]
            else:
                continue
            for base in bases:
                if base.split(".")[0] != "pendsweep":
                    continue
                found = [f"{base}.{n}" for n in names if f"{base}.{n}" in files] or [base]
                if found == [base] and base in files and base != name:
                    # Names taken from a package's own __init__ (``from . import figure``): an edge to the
                    # package even from its own submodule, whose import of the package is otherwise implied.
                    targets.add(base)
                for target in found:
                    parts = target.split(".")
                    for depth in range(2, len(parts) + 1):  # the target and its packages, not the root
                        module = ".".join(parts[:depth])
                        if module in files and not name.startswith(module + ".") and module != name:
                            targets.add(module)
        graph[name] = targets
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_import_graph_sees_lazy_imports():
    graph = _import_graph()  # the check below is only evidence if it reads imports inside functions too
    assert "pendsweep.studies.rig_sweep" in graph["pendsweep.studies.sweep"]  # imported inside functions only


def test_no_import_cycle_between_pendsweep_modules():
    cycles = _cycles(_import_graph())
    assert not cycles, "import circles: " + "; ".join(" <-> ".join(c) for c in cycles)


#: The longest a module may grow (issue 24 split the four over 680 lines, then hopf.py, along their concepts;
#: "about 500 lines": the longest are 570-580, each one concept).
MAX_MODULE_LINES = 600


def test_no_module_is_longer_than_one_concept_reads():
    long = {
        str(p.relative_to(SRC)): n for p in _python_files() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES
    }
    assert not long, f"split along their concepts: {long}"
