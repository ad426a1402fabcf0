"""Running OpenSees (openseespy) beside a site: where its libraries are and how its process must start.

openseespy 3.7.1.2 ships its own BLAS and LAPACK in ``openseespylinux/lib``,
which the dynamic loader does not search by itself: importing openseespy
fails unless ``LD_LIBRARY_PATH`` names that folder when the process starts.
The OpenSees side of a hybrid test therefore runs in its own process
(:func:`opensees_env` gives its environment). The model itself is
``examples/opensees_pendulum_site.py`` in the source tree.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

#: The runnable OpenSees example (the numerical substructure), in a source checkout.
EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "opensees_pendulum_site.py"


def opensees_library_dir() -> Path | None:
    """``openseespylinux/lib``, found without importing the package (whose import needs it); None if absent."""
    spec = importlib.util.find_spec("openseespylinux")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(spec.submodule_search_locations[0]) / "lib"


def opensees_env() -> dict[str, str]:
    """This process's environment with openseespy's libraries on ``LD_LIBRARY_PATH``."""
    env = dict(os.environ)
    lib = opensees_library_dir()
    if lib is not None:
        env["LD_LIBRARY_PATH"] = str(lib) + os.pathsep + env.get("LD_LIBRARY_PATH", "")
    return env


def run_example(port: int, alpha: float, fe: float, periods: int, host: str = "127.0.0.1") -> dict:
    """Run the example's OpenSees model against the site at ``host:port`` in a new process.

    Returns ``{"status": analyze's status, "wall": seconds of analyze}``. Raises
    ``RuntimeError`` when the process fails (its last error lines in the message).
    """
    code = (
        "import json, runpy\n"
        f"ns = runpy.run_path({str(EXAMPLE)!r})\n"
        f"status, wall = ns['build_and_run']({port}, {alpha}, {fe}, {periods}, ns['steps_per_period']({fe}), "
        f"host={host!r})\n"
        "print(json.dumps({'status': status, 'wall': wall}))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=opensees_env())
    if done.returncode != 0:
        raise RuntimeError(f"OpenSees failed: {done.stderr.strip()[-500:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])
