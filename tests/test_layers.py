"""The house's layers (issue 35): imports only downward, 0.1's paths kept one release, a rig's transport handed in.

``lint-imports`` (the contracts in pyproject.toml) is the check; these tests
show that it can fail, that old module paths still reach the same module
objects, that the substructured backend reaches a remote rig only through
a transport registered for the URL's scheme, and that the sweep
definitions have one home.
"""

import dataclasses
import importlib
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from pendsweep import _moved
from pendsweep.backends import make_backend
from pendsweep.backends.transports import register_rig_transport, rig_transport
from pendsweep.errors import ConfigError
from pendsweep.model.params import FIG11A

ROOT = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def _lint_imports(src: Path, cwd: Path) -> subprocess.CompletedProcess:
    env = {"PYTHONPATH": str(src), "PATH": str(LINT_IMPORTS.parent)}
    return subprocess.run(
        [str(LINT_IMPORTS), "--config", str(ROOT / "pyproject.toml"), "--no-cache"],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip


def test_lint_imports_passes_and_fails_on_a_deliberate_upward_import(tmp_path):
    kept = _lint_imports(ROOT / "src", tmp_path)
    assert kept.returncode == 0, kept.stdout + kept.stderr
    assert "0 broken" in kept.stdout

    shutil.copytree(ROOT / "src" / "pendsweep", tmp_path / "src" / "pendsweep", symlinks=True)
    backend = tmp_path / "src" / "pendsweep" / "backends" / "substructured.py"
    # the very import this issue removed: the backend driving its own client, lazily inside a function
    backend.write_text(backend.read_text() + "\n\ndef _remote():\n    from ..hybrid.client import run_remote\n")
    broken = _lint_imports(tmp_path / "src", tmp_path)
    assert broken.returncode == 1, broken.stdout
    assert "BROKEN" in broken.stdout
    assert "pendsweep.backends.substructured -> pendsweep.hybrid.client" in broken.stdout


def _imports_in_src():
    """(file, line, absolute module, names) of every pendsweep import in src/, lazy ones included."""
    import ast

    src = ROOT / "src"
    for path in sorted((src / "pendsweep").rglob("*.py")):
        parts = list(path.relative_to(src).with_suffix("").parts)
        package = parts if parts[-1] == "__init__" else parts[:-1]
        package = [p for p in package if p != "__init__"]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = package[: len(package) - node.level + 1] if node.level else []
                module = ".".join(base + ([node.module] if node.module else []))
                yield path, node.lineno, module, [a.name for a in node.names]
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    yield path, node.lineno, alias.name, []


def test_src_imports_no_old_path_and_not_the_facade():
    """What lint-imports cannot see: a 0.1 path (an alias, no file) or the root's lazy exports would hide an upward import."""
    src = ROOT / "src"
    bad = []
    for path, line, module, names in _imports_in_src():
        if module.split(".")[0] != "pendsweep":
            continue
        where = f"{path.relative_to(src)}:{line}"
        if module == "pendsweep":  # the package itself: its modules, never its lazy exports
            bad += [f"{where}: from pendsweep import {n}" for n in names if not (src / "pendsweep" / n).exists()
                    and not (src / "pendsweep" / f"{n}.py").exists()]  # fmt: skip
            continue
        file = src / module.replace(".", "/")
        if not (file.with_suffix(".py").exists() or (file / "__init__.py").exists()):
            bad.append(f"{where}: {module} is no module (a 0.1 path?)")
    assert not bad, bad


def test_the_public_api_resolves_lazily():
    code = "import sys, pendsweep; print('numpy' in sys.modules); [getattr(pendsweep, n) for n in pendsweep.__all__]"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert done.stdout.split() == ["False"]  # `import pendsweep` itself loads no numpy; every export resolves


@pytest.mark.parametrize(("old", "new"), sorted(_moved.MOVED.items()))
def test_an_old_module_path_is_the_moved_module_with_a_warning(old, new):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    moved = importlib.import_module(new)
    if hasattr(moved, "__path__"):  # a package: a stand-in giving the new package's names
        assert module.__moved_to__ == new
        assert all(
            getattr(module, n) is getattr(moved, n)
            for n in getattr(moved, "__all__", ())
            if f"{old}.{n}" not in _moved.MOVED
        )
    else:  # a module: the very module, keeping its own spec (pickling, reload)
        assert module is moved and module.__spec__.name == new
    assert any(issubclass(w.category, DeprecationWarning) and new in str(w.message) for w in caught)


def test_an_old_package_brings_its_submodules_in_either_form():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import pendsweep.diagnose.replay as replay_again  # noqa: I001 (the order is the point)
        from pendsweep.diagnose import replay, transfer
        from pendsweep.site import continuous
        from pendsweep.site.client import TCP_TRANSPORT
    from pendsweep.hybrid.client import TCP_TRANSPORT as moved
    from pendsweep.measured.diagnose.identify import transfer as moved_transfer
    from pendsweep.measured.diagnose.replay import whole
    from pendsweep.studies import rig_sweep

    assert TCP_TRANSPORT is moved and continuous is rig_sweep and transfer is moved_transfer
    assert replay is replay_again is whole  # 0.1's replay module, by either spelling


def test_old_paths_warn_at_the_users_line_under_default_filters(tmp_path):
    script = tmp_path / "user.py"
    script.write_text("from pendsweep.diagnose import replay\nimport pendsweep.site.rig\n")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, env=env)
    assert done.returncode == 0, done.stderr
    moved = "DeprecationWarning: pendsweep.diagnose.replay moved to pendsweep.measured.diagnose.replay.whole"
    assert f"{script}:1: {moved}" in done.stderr
    assert f"{script}:2: DeprecationWarning: pendsweep.site.rig moved to pendsweep.hybrid.rig" in done.stderr


def test_no_export_shares_its_name_with_an_old_path():
    """Old-path code binds ``pendsweep.<old>`` to a stand-in: an export of that name would be replaced."""
    import pendsweep

    assert not set(pendsweep.__all__) & {old.split(".")[1] for old in _moved.MOVED}


def test_old_paths_leave_the_new_packages_names_alone():
    import pendsweep.measured.diagnose as diagnosis

    stage = diagnosis.replay
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        importlib.import_module("pendsweep.diagnose.replay")  # 0.1's module of that name is replay.whole
    assert diagnosis.replay is stage and stage.__name__ == "pendsweep.measured.diagnose.replay"


@pytest.mark.parametrize("old", sorted(_moved.REMOVED))
def test_a_removed_module_is_not_found_and_names_its_successor(old):
    with pytest.raises(ModuleNotFoundError, match="pendsweep.measured.diagnose"):
        importlib.import_module(old)
    package, _, name = old.rpartition(".")
    with pytest.raises(ModuleNotFoundError, match="removed in pendsweep 0.2"):
        exec(f"from {package} import {name}", {})


class InProcessRig:
    """A transport whose 'remote' rig is the virtual one in this process, to show the contract is all it takes."""

    calls = 0

    def check(self, url: str) -> None:
        if not url.startswith("inprocess://"):
            raise ConfigError(f"rig = {url!r}; give inprocess://")

    def run(self, backend, params, state, transient, n_rec, trace_rows, stride):
        InProcessRig.calls += 1
        return dataclasses.replace(backend, rig="")._run(params, state, transient, n_rec, trace_rows, stride)


def test_a_rig_is_reached_through_the_transport_handed_in_for_its_scheme():
    register_rig_transport("inprocess", InProcessRig())
    local = make_backend("substructured")
    remote = make_backend("substructured", rig="inprocess://bench")
    state = local.initial_state(FIG11A, 0.0, 0.0, 0.1, 0.0)
    here = local.run_point(FIG11A, state, 3, 2)
    there = remote.run_point(FIG11A, state, 3, 2)
    assert InProcessRig.calls == 1
    np.testing.assert_array_equal(there.records, here.records)
    assert not remote.restartable  # a remote rig, whatever carries it


def test_a_continuous_test_needs_a_transport_that_holds_a_connection():
    from pendsweep.studies.sweep import SweepConfig, run_sweep

    register_rig_transport("inprocess", InProcessRig())  # runs points, has no open()
    with pytest.raises(ConfigError, match=r"single points only .*--mode fresh") as info:  # refused before it starts
        config = SweepConfig("alpha", (4.0, 4.5), backend="substructured",
                             backend_options={"rig": "inprocess://bench"}, mode="continue", kick=0.0)  # fmt: skip
        run_sweep(config)
    assert "\n" not in str(info.value)


def test_a_transport_that_does_not_load_is_one_line(monkeypatch):
    from importlib.metadata import EntryPoint

    from pendsweep.backends import transports

    broken = EntryPoint("broken", "no_such_module_anywhere:RIG", transports.ENTRY_POINT_GROUP)
    monkeypatch.setattr(
        transports, "entry_points", lambda **kw: [broken] if kw.get("name", "broken") == "broken" else []
    )
    with pytest.raises(ConfigError, match="no_such_module_anywhere:RIG .* does not load: ModuleNotFoundError") as info:
        rig_transport("broken://x")
    assert "\n" not in str(info.value)


def test_tcp_is_the_installed_transport_and_an_unknown_scheme_is_one_line():
    from pendsweep.hybrid.client import TCP_TRANSPORT

    assert rig_transport("tcp://127.0.0.1:8090") is TCP_TRANSPORT  # found by its entry point
    with pytest.raises(ConfigError, match=r"give tcp://HOST:PORT .*transports installed: .*tcp") as info:
        make_backend("substructured", rig="udp://127.0.0.1:1")
    assert "\n" not in str(info.value)


def test_the_sweep_definitions_have_one_home():
    from pendsweep.studies.sweepfile import SWEEPS_DIR, builtin_sweeps

    assert SWEEPS_DIR.resolve() == (ROOT / "sweeps").resolve()  # a checkout reads the top-level folder
    assert sorted(builtin_sweeps()) == sorted(p.stem for p in (ROOT / "sweeps").glob("*.toml")) == ["fig11a", "fig11b"]
