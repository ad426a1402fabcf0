"""``python -m pendsweep``: the ``pendsweep`` command."""

from .cli import run

run()
