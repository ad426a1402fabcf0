"""The click group shared by every pendsweep command."""

from __future__ import annotations

import math

import click

from .._version import __version__
from ..errors import PendsweepError


class UsageFailure(click.ClickException):
    """A clear one-line error with exit status 2 (bad input, bad file)."""

    exit_code = 2


class _Group(click.Group):
    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except PendsweepError as exc:
            raise UsageFailure(str(exc)) from None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="pendsweep")
def main() -> None:
    """Bifurcation sweeps of the coupled pendulum-oscillator system.

    Units are SI throughout: forces in N, masses in kg, frequencies in Hz,
    lengths in m, angles in rad, times in s.
    """


class FiniteFloat(click.ParamType):
    """A float that must be finite (NaN and inf are rejected with exit 2)."""

    name = "float"

    def convert(self, value, param, ctx):
        if isinstance(value, float) and math.isfinite(value):
            return value
        try:
            v = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(v):
            self.fail(f"{value!r} is not finite; give a finite number", param, ctx)
        return v


FINITE = FiniteFloat()
