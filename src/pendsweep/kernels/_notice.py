"""One line on stderr when numba starts compiling pendsweep's kernels in a process.

A cold numba cache (a fresh install, a new machine, a CI runner) makes the
first command compile its kernels, tens of seconds with nothing else to
show. numba broadcasts a ``numba:compile`` event only when a function is
really compiled, never when it is loaded from its cache, so a warm cache
prints nothing.
"""

import sys

from numba.core import event
from numba.core.registry import CPUDispatcher

MESSAGE = (
    "pendsweep: compiling numba kernels for this machine; only the first run compiles them "
    "(numba caches them; `pendsweep warmup` compiles every command's ahead)"
)


class _FirstCompile(event.Listener):
    """Prints :data:`MESSAGE` when the first of pendsweep's CPU kernels starts compiling."""

    def __init__(self) -> None:
        self.told = False

    def on_start(self, ev: event.Event) -> None:
        dispatcher = ev.data["dispatcher"]
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", None) or ""
        if not self.told and isinstance(dispatcher, CPUDispatcher) and module.startswith("pendsweep."):
            self.told = True
            print(MESSAGE, file=sys.stderr, flush=True)

    def on_end(self, ev: event.Event) -> None:
        pass


def announce_compilation() -> None:
    """Print :data:`MESSAGE` once in this process, when numba first compiles a pendsweep kernel."""
    event.register("numba:compile", _FirstCompile())
