"""The click group shared by every pendsweep command, and the value types of its options."""

from __future__ import annotations

import math
from pathlib import Path

import click
from click.core import ParameterSource

from .._version import __version__
from ..errors import PendsweepError
from ..studies.sweepfile import MAX_ANGLE, MAX_PERIODS


class UsageFailure(click.ClickException):
    """A clear one-line error with exit status 2 (bad input, bad file)."""

    exit_code = 2


class RuntimeFailure(click.ClickException):
    """A clear one-line error with exit status 1 (the work itself failed)."""

    exit_code = 1


#: click >= 8.2 shows a group's help through this UsageError when no command is given.
_HELP_ON_NO_ARGS = getattr(click.exceptions, "NoArgsIsHelpError", ())


class _Group(click.Group):
    # click's own usage errors (an unknown option, a value outside an IntRange)
    # print usage and a hint before the error: one line here, like ours.
    def make_context(self, *args, **kwargs) -> click.Context:
        try:
            return super().make_context(*args, **kwargs)
        except _HELP_ON_NO_ARGS:
            raise
        except click.UsageError as exc:
            raise UsageFailure(exc.format_message()) from None

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except _HELP_ON_NO_ARGS:
            raise
        except click.UsageError as exc:
            raise UsageFailure(exc.format_message()) from None
        except PendsweepError as exc:
            if exc.exit_code not in (1, 2):  # e.g. a rig test stopped by SIGINT: the shell's 130
                failure = click.ClickException(str(exc))
                failure.exit_code = exc.exit_code
                raise failure from None
            cls = RuntimeFailure if exc.exit_code == 1 else UsageFailure
            raise cls(str(exc)) from None
        except OSError as exc:  # a disk filling up or a file vanishing mid-run: not the command line's fault
            name = f" {str(exc.filename)!r}" if exc.filename else ""
            raise RuntimeFailure(f"{exc.strerror or exc}{name}") from None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="pendsweep")
def main() -> None:
    """Bifurcation sweeps of the coupled pendulum-oscillator system.

    Units are SI throughout: forces in N, masses in kg, frequencies in Hz,
    lengths in m, angles in rad, times in s. Bad input exits with status 2
    and a one-line message; a failure while running exits with status 1.
    """


class FiniteFloat(click.ParamType):
    """A finite float, optionally within ``[lo, hi]`` (NaN, inf and values outside exit 2).

    Parameters
    ----------
    lo, hi : float
        Inclusive bounds (default unbounded).
    unit : str
        Unit named in the error message, e.g. ``"rad"``.
    """

    name = "float"

    def __init__(self, lo: float = -math.inf, hi: float = math.inf, unit: str = "") -> None:
        self.lo, self.hi, self.unit = lo, hi, unit

    def convert(self, value, param, ctx):
        if isinstance(value, float) and math.isfinite(value) and self.lo <= value <= self.hi:
            return value
        try:
            v = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(v):
            self.fail(f"{value!r} is not finite; give a finite number", param, ctx)
        if not self.lo <= v <= self.hi:
            unit = f" {self.unit}" if self.unit else ""
            self.fail(f"{value!r}{unit} is outside the accepted range [{self.lo:g}, {self.hi:g}]{unit}", param, ctx)
        return v


FINITE = FiniteFloat()
#: Initial angles: 5 turns either way (sin and cos of larger floats lose digits; angles wrap anyway).
ANGLE = FiniteFloat(-MAX_ANGLE, MAX_ANGLE, "rad")
#: Initial angular rates: far above anything the pendulum reaches (omega_p ~ 7 rad/s).
RATE = FiniteFloat(-1e3, 1e3, "rad/s")
#: Kicks and thresholds on angles.
SMALL_ANGLE = FiniteFloat(0.0, math.pi, "rad")
#: Integration / controller steps: 1 microsecond to 10 ms (the paper's is 1 ms).
STEP_S = FiniteFloat(1e-6, 1e-2, "s")
#: Seeds of numpy's generators (non-negative, below 2**63).
SEED = click.IntRange(0, 2**63 - 1)
#: Forcing periods simulated per point.
PERIODS = click.IntRange(0, MAX_PERIODS)


class LazyChoice(click.Choice):
    """A :class:`click.Choice` whose choices are loaded on first use (e.g. the backend registry).

    Building the command line then imports no simulation code: ``pendsweep
    --help`` stays fast, and a subcommand loads what it needs when it runs.

    Parameters
    ----------
    module : str
        Module (relative to ``pendsweep``) holding the choices, e.g. ``".backends"``.
    attribute : str
        Name of the iterable of choices in it (sorted for display).
    """

    def __init__(self, module: str, attribute: str) -> None:  # click.Choice.__init__ would load them now
        self._source = (module, attribute)
        self.case_sensitive = True

    @property
    def choices(self) -> tuple[str, ...]:
        import importlib

        module, attribute = self._source
        return tuple(sorted(getattr(importlib.import_module(module, "pendsweep"), attribute)))


class NonEmptyPath(click.ParamType):
    """A file or folder name, refused when empty (click would turn `` into `.`), as :class:`pathlib.Path`."""

    name = "path"

    def convert(self, value, param, ctx):
        if isinstance(value, Path):
            return value
        if not str(value).strip():
            self.fail(f"{value!r} is not a file name", param, ctx)
        return Path(value)


PATH = NonEmptyPath()


def given(ctx: click.Context, name: str) -> bool:
    """True when option ``name`` was set on the command line or from the environment."""
    return ctx.get_parameter_source(name) in (ParameterSource.COMMANDLINE, ParameterSource.ENVIRONMENT)
