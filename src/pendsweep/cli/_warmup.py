"""``pendsweep warmup``: compile every command's numba kernels once, ahead of their first real run.

numba compiles a kernel at its first call and caches it on disk; with a cold
cache (a fresh install, a new machine, a CI runner) the first command pays
for it. ``make setup`` runs this command, so that ``make run`` and the
first sweep start warm. Each step runs a real command on a tiny problem in
a scratch folder: the kernels compiled are exactly those the command uses.
"""

from __future__ import annotations

import contextlib
import io
import tempfile
import time

import click

from ._app import RuntimeFailure, main

#: (what a step prepares, the command line it runs): a point or a few cells, a few periods each.
STEPS = (
    ("sweeps in continue mode (the canonical `pendsweep alpha`)", ["alpha", "--from", "10", "--to", "10", "-o", "c.parquet"]),
    ("sweeps in fresh and multistart mode", ["alpha", "--from", "10", "--to", "10", "--mode", "fresh", "-o", "f.parquet"]),
    ("basins", ["basins", "--alpha", "40", "--grid", "2x2", "--max-periods", "30", "-o", "b.parquet"]),
    ("map", ["map", "alpha", "fe", "--alpha", "30:40:2", "--fe", "2.4:2.6:2", "--max-periods", "30", "-o", "m.parquet"]),
    ("continue", ["continue", "alpha", "--from", "20", "--to", "20.2", "-o", "o.json"]),
    ("hopf", ["hopf", "--what", "1.1087", "--method", "analytic,floquet,simulate", "-o", "h.parquet"]),
)  # fmt: skip


def run_step(argv: list[str]) -> None:
    """Run ``pendsweep ARGV`` in this process, its output discarded; raises what the command raises."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        main.main(argv, prog_name="pendsweep", standalone_mode=False)


@main.command("warmup")
def warmup() -> None:
    """Compile every command's numba kernels now, into numba's cache (`make setup` runs it).

    The first run of a command after an install otherwise compiles them
    first (tens of seconds to a minute; a line on stderr says so). Each step
    runs the command on a tiny problem in a scratch folder and prints its time.
    """
    failed = []
    with tempfile.TemporaryDirectory(prefix="pendsweep-warmup-") as scratch, contextlib.chdir(scratch):
        for what, argv in STEPS:
            t0 = time.perf_counter()
            try:
                run_step(argv)
            except Exception as exc:  # one command's failure must not keep the others cold
                failed.append(what)
                click.echo(f"warmup: {what}: failed ({exc})", err=True)
                continue
            click.echo(f"warmup: {what}: {time.perf_counter() - t0:.1f} s")
    if failed:
        raise RuntimeFailure(f"warmup: {len(failed)} of {len(STEPS)} steps failed: {', '.join(failed)}")
