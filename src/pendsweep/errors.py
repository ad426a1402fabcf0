"""Exceptions that the CLI turns into a clear message and exit status 2."""


class PendsweepError(Exception):
    """Base class for user-facing errors (bad input, bad files, bad config)."""


class ParameterError(PendsweepError, ValueError):
    """A parameter value outside its accepted range (the message names both)."""


class ConfigError(PendsweepError, ValueError):
    """A malformed sweep definition or option."""


class ResultsError(PendsweepError, OSError):
    """A results file that cannot be written, read or resumed."""
