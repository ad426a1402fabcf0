"""``--executor`` and ``--scheduler``: the options every scan command shares."""

from __future__ import annotations

from typing import Callable

import click

from ..executors import EXECUTORS, SCHEDULER_ENV


def executor_options() -> list[Callable]:
    """click options ``--executor local|dask`` and ``--scheduler ADDRESS``."""
    return [
        click.option(
            "--executor", type=click.Choice(EXECUTORS), default="local", show_default=True,
            help="Where points run: local (this machine's cores) or dask (chunks of points on a "
            "dask.distributed cluster; results stream into the same resumable file).",
        ),
        click.option(
            "--scheduler", default=None, metavar="ADDRESS",
            help=f"Dask scheduler for --executor dask, e.g. tcp://10.0.0.5:8786 (default: ${SCHEDULER_ENV}).",
        ),
    ]


def apply_options(options: list[Callable]) -> Callable:
    """Decorator applying a list of click options in order."""

    def deco(fn):
        for opt in reversed(options):
            fn = opt(fn)
        return fn

    return deco
