"""Options every scan command shares: ``--executor``, ``--scheduler``, ``--max-work``, ``--yes``."""

from __future__ import annotations

from collections.abc import Callable

import click

from ..engine.executors import EXECUTORS, SCHEDULER_ENV
from ..engine.scan import DEFAULT_MAX_WORK
from ._app import FiniteFloat


def executor_options() -> list[Callable]:
    """click options ``--executor local|dask`` and ``--scheduler ADDRESS``."""
    return [
        click.option(
            "--executor",
            type=click.Choice(EXECUTORS),
            default="local",
            show_default=True,
            help="Where points run: local (this machine's cores) or dask (chunks of points on a "
            "dask.distributed cluster; results stream into the same resumable file).",
        ),
        click.option(
            "--scheduler",
            default=None,
            metavar="ADDRESS",
            help=f"Dask scheduler for --executor dask, e.g. tcp://10.0.0.5:8786 (default: ${SCHEDULER_ENV}).",
        ),
    ]


def work_options(default: float | None = DEFAULT_MAX_WORK, default_text: str = "") -> list[Callable]:
    """click options ``--max-work STEPS`` and ``--yes``: the limit on a scan's work estimate.

    ``default`` None: the command picks it (``default_text`` says how, in the help).
    """
    return [
        click.option(
            "--max-work",
            type=FiniteFloat(1.0, 1e30, "steps"),
            default=default,
            show_default=default is not None,
            metavar="STEPS",
            help="Refuse scans estimated above this many integration steps (points x periods x steps per period)"
            + (f"; default {default_text}." if default_text else "."),
        ),
        click.option(
            "--yes",
            "-y",
            "yes",
            is_flag=True,
            help="Run whatever the estimates (lifts --max-work and the memory check).",
        ),
    ]


def max_work(limit: float, yes: bool) -> float | None:
    """The work limit to pass on: None (no limit) with ``--yes``."""
    return None if yes else limit


#: Longest checkpoint interval [s] the command line accepts (an hour of finished work at risk).
MAX_CHECKPOINT_SECONDS = 3600.0


def checkpoint_option() -> Callable:
    """click option ``--checkpoint-seconds S``: how often a resumable scan persists finished units."""
    return click.option(
        "--checkpoint-seconds",
        type=FiniteFloat(0.0, MAX_CHECKPOINT_SECONDS, "s"),
        default=1.0,
        show_default=True,
        help="A finished unit is written to <output>.parts at most this long after it finishes, "
        f"s, 0 to {MAX_CHECKPOINT_SECONDS:g} (0: at once); a killed run resumes from there.",
    )


def apply_options(options: list[Callable]) -> Callable:
    """Decorator applying a list of click options in order."""

    def deco(fn):
        for opt in reversed(options):
            fn = opt(fn)
        return fn

    return deco
