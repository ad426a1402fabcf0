"""The diagnosis is one pipeline (issue 35): identify, replay, fit, judge, report, one room per stage.

A walk of one record through :func:`~pendsweep.measured.diagnose.diagnose` and through
:func:`~pendsweep.measured.diagnose.diagnose_parts` enters each stage once, in order.

The walk is what the driver (:mod:`pendsweep.measured.diagnose.pipeline`) does: every call
from a driver frame into a module of the diagnosis package (through any library frames between
them, such as joblib's) is attributed to the stage it lands in, the top-level package or module
under ``pendsweep.measured.diagnose``; consecutive calls into one stage are one stay. The helper
modules several stages share (:data:`HELPERS`: the effect vocabulary, the signal helpers, the
residual features) are no stage and are not counted. What a stage calls inside itself, the
methods of the results handed to it included (a fit simulates its replays), stays in its room.

Before the regrouping the same walk made 16 stays in 5 modules (11 returns) through ``diagnose``
and 48 stays in 8 modules (40 returns) through ``diagnose_parts``.
"""

import ast
import sys
from pathlib import Path

import pytest

from pendsweep.measured.diagnose import Replay, diagnose, diagnose_parts
from pendsweep.measured.diagnose.testbench import TEST_SEEDS, Case, generate

PACKAGE = "pendsweep.measured.diagnose"
STAGES = ("identify", "replay", "fit", "judge", "report")
HELPERS = {"effects", "signals", "signatures"}
DRIVERS = {"diagnose", "diagnose_parts", "diagnose_records"}
SOURCE = Path(__file__).resolve().parents[1] / "src" / "pendsweep" / "measured" / "diagnose"
SEED = TEST_SEEDS[0] + 3500


def _module(frame) -> str:
    return frame.f_globals.get("__name__", "")


def _is_driver(frame) -> bool:
    name = getattr(frame.f_code, "co_qualname", frame.f_code.co_name)
    return _module(frame) == f"{PACKAGE}.pipeline" and name.split(".")[0] in DRIVERS


def walk(function, *args):
    """``function(*args)`` and the stages its driver entered, consecutive repeats collapsed."""
    stays: list[str] = []

    def profile(frame, event, arg):
        if event != "call" or not _module(frame).startswith(PACKAGE + ".") or _is_driver(frame):
            return
        caller = frame.f_back
        while caller is not None and not _module(caller).startswith(PACKAGE):
            caller = caller.f_back  # joblib's, numpy's frames between the driver and a stage
        if caller is None or not _is_driver(caller):
            return
        stage = _stage_of(_module(frame))  # the driver module's own helpers are the driver, not a stage
        if stage in STAGES and (not stays or stays[-1] != stage):
            stays.append(stage)

    previous = sys.getprofile()
    sys.setprofile(profile)
    try:
        result = function(*args)
    finally:
        sys.setprofile(previous)
    return result, stays


def _assert_one_pass(stays: list[str], expected: list[str]) -> None:
    returns = [s for i, s in enumerate(stays) if s in stays[:i]]
    assert not returns, f"the walk returns to {returns}: {stays}"
    assert stays == expected, stays
    assert stays == sorted(stays, key=STAGES.index), f"stages out of order: {stays}"


def test_a_record_walks_through_diagnose_once_per_stage():
    record = generate(Case("free_decay", seed=SEED, theta_init=1.0, duration=4.0))
    diag, stays = walk(diagnose, Replay(record))
    assert diag.cause == "none"
    # The caller made the replay; the driver hands it on to the fit and the judge.
    _assert_one_pass(stays, ["replay", "fit", "judge"])


def test_a_record_walks_through_diagnose_parts_once_per_stage():
    record = generate(Case("substructured", seed=SEED + 1, theta_init=0.3, duration=4.0))
    diag, stays = walk(diagnose_parts, [record])
    assert diag.physical is not None and diag.numerical is not None  # both parts fitted and judged
    _assert_one_pass(stays, ["identify", "replay", "fit", "judge"])


def _stage_of(module: str) -> str | None:
    """The stage (or helper) a module of the package belongs to; None for the driver and the rest."""
    head = module[len(PACKAGE) + 1 :].split(".")[0] if module.startswith(PACKAGE + ".") else ""
    return head if head in STAGES or head in HELPERS else None


def _imports(path: Path, module: str) -> set[str]:
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([node.module] if node.module else []))
            out.add(base)
        elif isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
    return out


@pytest.mark.parametrize("stage", [*STAGES, *sorted(HELPERS)])
def test_a_stage_reads_only_earlier_stages_results(stage):
    """Data flows forward: a stage imports the stages before it (their results) and the helpers, never
    a later stage; a helper imports no stage."""
    root = SOURCE / stage if (SOURCE / stage).is_dir() else SOURCE / f"{stage}.py"
    files = sorted(root.rglob("*.py")) if root.is_dir() else [root]
    assert files
    for path in files:
        parts = path.relative_to(SOURCE.parents[2]).with_suffix("").parts
        module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        for target in _imports(path, module):
            other = _stage_of(target)
            if other is None or other == stage:
                continue
            assert other in HELPERS or (stage in STAGES and STAGES.index(other) < STAGES.index(stage)), (
                f"{module} imports {target}"
            )
