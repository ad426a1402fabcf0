"""Exceptions that the CLI turns into a clear one-line message.

Bad input (a value out of range, a malformed or wrong-kind file, an
unwritable output path) exits with status 2; a failure while running
(:class:`RunFailure`, e.g. a corrupt results file met while resuming) exits
with status 1. The status is each class's ``exit_code``.
"""


class PendsweepError(Exception):
    """Base class for user-facing errors (bad input, bad files, bad config)."""

    exit_code = 2


class ParameterError(PendsweepError, ValueError):
    """A parameter value outside its accepted range (the message names both)."""


class ConfigError(PendsweepError, ValueError):
    """A malformed sweep definition or option."""


class ResultsError(PendsweepError, OSError):
    """A results file that cannot be written, read or resumed."""


class RunFailure(PendsweepError, RuntimeError):
    """A failure while the work runs, not caused by the command line (exit status 1)."""

    exit_code = 1


class CorruptResultsError(ResultsError, RunFailure):
    """A results or part file that exists but cannot be read back (exit status 1)."""

    exit_code = 1
