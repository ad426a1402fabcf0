"""The house's layers (issue 35): imports only downward, 0.1's paths kept one release, a rig's transport handed in.

``lint-imports`` (the contracts in pyproject.toml) is the check; these tests
show that it can fail, that old module paths still reach the same module
objects, that the substructured backend reaches a remote rig only through
a transport registered for the URL's scheme, and that the sweep
definitions have one home.
"""

import dataclasses
import importlib
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


def test_the_public_api_resolves_lazily():
    code = "import sys, pendsweep; print('numpy' in sys.modules); [getattr(pendsweep, n) for n in pendsweep.__all__]"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert done.stdout.split() == ["False"]  # `import pendsweep` itself loads no numpy; every export resolves


@pytest.mark.parametrize(("old", "new"), sorted(_moved.MOVED.items()))
def test_an_old_module_path_is_the_moved_module_with_a_warning(old, new):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    assert module is importlib.import_module(new)
    assert module.__spec__.name == new  # the module keeps its own spec (pickling, reload)
    assert any(issubclass(w.category, DeprecationWarning) and new in str(w.message) for w in caught)


def test_an_old_package_brings_its_submodules():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from pendsweep.site.client import TCP_TRANSPORT
        from pendsweep.site.continuous import rig_test
    from pendsweep.hybrid.client import TCP_TRANSPORT as moved
    from pendsweep.studies.rig_sweep import rig_test as moved_test

    assert TCP_TRANSPORT is moved and rig_test is moved_test


@pytest.mark.parametrize("old", sorted(_moved.REMOVED))
def test_a_removed_module_is_not_found(old):
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module(old)


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
