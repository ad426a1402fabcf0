"""Module paths of pendsweep 0.1 that moved in the regrouping into layer packages: kept for one release.

``import pendsweep.sweep`` (or ``from pendsweep.site.client import ...``)
still works and gives the module at its new path, the very same module
object, with a :class:`DeprecationWarning` naming the new path. The old
paths go in pendsweep 0.3; CHANGELOG.md lists them and the modules that
were removed instead.

The finder (``pendsweep._OldPaths``, installed by ``import pendsweep``) asks
:func:`find_spec` only for a name no file answers, or a submodule of an old
package, so this module is imported only when an old path is used.
"""

from __future__ import annotations

import importlib
import sys
import warnings
from importlib.machinery import ModuleSpec

#: Old path -> new path; an old package's submodules follow it (``pendsweep.site.rig`` -> ``pendsweep.hybrid.rig``).
MOVED = {
    "pendsweep.params": "pendsweep.model.params",
    "pendsweep.analytic": "pendsweep.model.analytic",
    "pendsweep.loop": "pendsweep.model.loop",
    "pendsweep._vector_width": "pendsweep.kernels._vector_width",
    "pendsweep.gpu": "pendsweep.backends.gpu",
    "pendsweep.status": "pendsweep.backends.status",
    "pendsweep.scan": "pendsweep.engine.scan",
    "pendsweep.executors": "pendsweep.engine.executors",
    "pendsweep.results": "pendsweep.engine.results",
    "pendsweep.merge": "pendsweep.engine.merge",
    "pendsweep.columns": "pendsweep.engine.columns",
    "pendsweep.output_lock": "pendsweep.engine.output_lock",
    "pendsweep.classify": "pendsweep.analysis.classify",
    "pendsweep.sections": "pendsweep.analysis.sections",
    "pendsweep.attractors": "pendsweep.analysis.attractors",
    "pendsweep.semi_trivial": "pendsweep.analysis.semi_trivial",
    "pendsweep.hopf_protocol": "pendsweep.analysis.hopf_protocol",
    "pendsweep.stability": "pendsweep.analysis.stability",
    "pendsweep.continuation.overlay": "pendsweep.figures.overlay",
    "pendsweep.continuation": "pendsweep.analysis.continuation",
    "pendsweep.site.continuous": "pendsweep.studies.rig_sweep",
    "pendsweep.site": "pendsweep.hybrid",
    "pendsweep.sync": "pendsweep.hybrid.sync",
    "pendsweep.sweep": "pendsweep.studies.sweep",
    "pendsweep.sweep_rows": "pendsweep.studies.sweep_rows",
    "pendsweep.sweepfile": "pendsweep.studies.sweepfile",
    "pendsweep.maps": "pendsweep.studies.maps",
    "pendsweep.hopf": "pendsweep.studies.hopf",
    "pendsweep.basins": "pendsweep.studies.basins",
    "pendsweep.data": "pendsweep.measured.records",
    "pendsweep.logs": "pendsweep.measured.logs",
    "pendsweep.diagnose": "pendsweep.measured.diagnose",
    # the diagnosis's modules that moved whole into a pipeline stage (issue 35)
    "pendsweep.diagnose.identify": "pendsweep.measured.diagnose.identify.oscillator",
    "pendsweep.diagnose.transfer": "pendsweep.measured.diagnose.identify.transfer",
    "pendsweep.diagnose.servo_step": "pendsweep.measured.diagnose.identify.servo_step",
    "pendsweep.diagnose.replay": "pendsweep.measured.diagnose.replay.whole",
    "pendsweep.diagnose.parts": "pendsweep.measured.diagnose.replay.parts",
    "pendsweep.diagnose.fitting": "pendsweep.measured.diagnose.fit.least_squares",
    "pendsweep.plotting": "pendsweep.figures.plotting",
}
#: 0.1 modules that are gone, each with where its pieces went (CHANGELOG.md has the full list).
REMOVED = {
    "pendsweep.diagnose.fit": "diagnose and Diagnosis are in pendsweep.measured.diagnose (stages fit, judge)",
    "pendsweep.diagnose.judging": "its tests are in pendsweep.measured.diagnose.judge.tests, the ranking in .fit",
    "pendsweep.diagnose.thresholds": "the thresholds are in pendsweep.measured.diagnose.fit and .judge.tests",
    "pendsweep.diagnose.chain": "diagnose_parts is in pendsweep.measured.diagnose (pipeline; judge.parts)",
    "pendsweep.diagnose.parts_report": "the parts' report is in pendsweep.measured.diagnose.report",
}


def new_path(name: str) -> str | None:
    """Where the 0.1 module ``name`` lives now, or None if it did not move."""
    if name in MOVED:
        return MOVED[name]
    old = max((k for k in MOVED if name.startswith(k + ".")), key=len, default=None)
    return None if old is None else MOVED[old] + name[len(old) :]


def _warn_moved(message: str) -> None:
    """A DeprecationWarning blamed on the user's line, past this module's and importlib's frames.

    ``warnings.warn``'s stacklevel cannot reach it: the number of frames
    between an old path and the code that named it depends on how it was
    named (``import a.b``, ``from a import b``, ``a.b``), and the default
    filters show the warning only when it is blamed on ``__main__``.
    """
    frame = sys._getframe(1)
    while frame is not None and (frame.f_code.co_filename == __file__ or "importlib" in frame.f_code.co_filename):
        frame = frame.f_back
    if frame is None:
        warnings.warn(message, DeprecationWarning, stacklevel=2)
        return
    g = frame.f_globals
    warnings.warn_explicit(
        message, DeprecationWarning, frame.f_code.co_filename, frame.f_lineno,
        module=g.get("__name__", "<unknown>"), registry=g.setdefault("__warningregistry__", {}),
    )  # fmt: skip


class _OldPackage(type(sys)):
    """0.1's package at its old path: a stand-in for the package at ``__moved_to__``.

    A name is the new package's, except a 0.1 submodule, which is the old one
    (its alias, or the reason it is gone): ``from pendsweep.diagnose import
    replay`` is 0.1's replay module, as ``import pendsweep.diagnose.replay``
    is. Old code binding its submodules here leaves the new package's names
    alone.
    """

    def __init__(self, name: str, new: str) -> None:
        super().__init__(name, f"0.1's {name}, now {new} (pendsweep._moved)")
        self.__path__: list[str] = []  # a package: its submodules are looked up, by the finder in pendsweep
        self.__moved_to__ = new

    def __getattr__(self, attr: str):
        if attr.startswith("__"):
            raise AttributeError(attr)
        old = f"{self.__name__}.{attr}"
        if old in REMOVED or old in MOVED:
            return importlib.import_module(old)
        package = importlib.import_module(self.__moved_to__)
        if hasattr(package, attr):
            return getattr(package, attr)
        try:
            return importlib.import_module(old)
        except ModuleNotFoundError as exc:
            if exc.name != new_path(old):
                raise
            raise AttributeError(f"module {self.__name__!r} has no attribute {attr!r}") from None


class _Alias:
    """The loader of an old path: the module at its new path.

    A module is the very module at its new path; a package is an :class:`_OldPackage`.
    """

    def __init__(self, new: str) -> None:
        self.new = new

    def create_module(self, spec):
        _warn_moved(f"{spec.name} moved to {self.new}; the old path goes in pendsweep 0.3")
        module = importlib.import_module(self.new)
        if hasattr(module, "__path__"):
            return _OldPackage(spec.name, self.new)
        self.own_spec = module.__spec__
        return module

    def exec_module(self, module) -> None:
        if not isinstance(module, _OldPackage):
            module.__spec__ = self.own_spec  # the import system gave it the alias's spec: it keeps its own


def find_spec(name: str) -> ModuleSpec | None:
    """The spec of 0.1's module path ``name`` (an alias of its new path), or None if it is no old path.

    Raises :class:`ModuleNotFoundError` naming the successor of a module that was removed.
    """
    if name in REMOVED:
        raise ModuleNotFoundError(f"{name} was removed in pendsweep 0.2: {REMOVED[name]}", name=name)
    new = new_path(name)
    return None if new is None else ModuleSpec(name, _Alias(new))
