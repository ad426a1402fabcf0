"""Checks every command runs before it starts work: output paths, input files, options that do not apply."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

from ..errors import ConfigError

FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def backend_option(example: str):
    """The ``-B/--backend-option KEY=VALUE`` option (repeatable, into ``backend_opts``), with an example."""
    import click

    return click.option(
        "-B", "--backend-option", "backend_opts", multiple=True, metavar="KEY=VALUE", help=f"Backend option, {example}"
    )


def check_output(path: Path | None, option: str, suffixes: Iterable[str] = ()) -> Path | None:
    """Refuse an output file that could not be written, before any work starts.

    Parameters
    ----------
    path : Path or None
        The file the command will write (``None``: nothing to check).
    option : str
        The option or argument that gave it, named in the message (e.g. ``"-o"``).
    suffixes : iterable of str
        Accepted endings (lower case, with the dot); empty accepts any.

    Raises
    ------
    ConfigError
        (exit 2) naming the path and what is accepted: an empty name, a wrong
        ending, a directory, a parent that is a file, or a folder where files
        cannot be created. Nothing is created on disk by the check.
    """
    if path is None:
        return None
    text = str(path)
    suffixes = tuple(suffixes)
    accepted = f"a file name ending in {' or '.join(suffixes)}" if suffixes else "a file name"
    if not text.strip() or text in (".", ".."):
        raise ConfigError(f"{option} {text!r} is not a file name; give {accepted}")
    path = Path(path)
    if suffixes and path.suffix.lower() not in suffixes:
        raise ConfigError(f"{option} {text!r} must end in {' or '.join(suffixes)}")
    if path.is_dir():
        raise ConfigError(f"{option} {text!r} is a directory; give {accepted}")
    _check_folder(path.parent, option, text)
    if path.exists() and not os.access(path, os.W_OK):
        raise ConfigError(f"cannot write {option} {text!r}: the file exists and is not writable")
    return path


def positional_or_output(positional: Path | None, output: Path | None, argument: str) -> tuple[Path, str]:
    """The output file given either as the positional ``argument`` (the old spelling) or as ``-o/--output``.

    Returns the path and how it was spelled (for messages). Exactly one must be given (ConfigError, exit 2).
    """
    if positional is not None and output is not None:
        raise ConfigError(f"give the output once: {argument} {str(positional)!r} or -o {str(output)!r}, not both")
    if positional is None and output is None:
        raise ConfigError(f"no output file: give -o/--output FILE (or {argument} as the first argument)")
    return (output, "-o") if output is not None else (positional, argument)


def check_output_dir(path: Path | None, option: str) -> Path | None:
    """Like :func:`check_output` for an output folder (created later by the command)."""
    if path is None:
        return None
    text = str(path)
    if not text.strip():
        raise ConfigError(f"{option} {text!r} is not a folder name")
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{option} {text!r} is a file; give a folder")
    _check_folder(path, option, text)
    return path


def _check_folder(folder: Path, option: str, text: str) -> None:
    existing = folder
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if not existing.is_dir():
        raise ConfigError(f"cannot write {option} {text!r}: {str(existing)!r} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ConfigError(f"cannot write {option} {text!r}: folder {str(existing)!r} is not writable")
    try:  # permissions are not the whole story (read-only mounts, /proc, /sys)
        fd, probe = tempfile.mkstemp(dir=existing, prefix=".pendsweep-write-test-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ConfigError(
            f"cannot write {option} {text!r}: cannot create files in {str(existing)!r} ({exc.strerror or exc})"
        ) from None


def check_input(path: Path, what: str) -> Path:
    """Refuse a missing, unreadable or non-file input before any work starts."""
    path = Path(path)
    if not str(path).strip():
        raise ConfigError(f"{what} {str(path)!r} is not a file name")
    if not path.exists():
        raise ConfigError(f"no {what} at {str(path)!r}")
    if path.is_dir():
        raise ConfigError(f"{what} {str(path)!r} is a directory, not a file")
    if not os.access(path, os.R_OK):
        raise ConfigError(f"{what} {str(path)!r} is not readable")
    return path


def check_not_an_input(path: Path | None, option: str, inputs: Iterable[Path]) -> None:
    """Refuse an output that would overwrite an input record or its ``.json`` sidecar (a CSV record's metadata)."""
    if path is None:
        return
    target = Path(path).resolve()
    for record in inputs:
        record = Path(record).resolve()
        if target in (record, record.with_suffix(".json")):
            raise ConfigError(f"{option} {str(path)!r} would overwrite the input {str(record)!r} or its .json sidecar")


def key_values(pairs: Iterable[str], what: str) -> dict[str, str]:
    """``NAME=VALUE`` strings (e.g. ``-B signum=stage``) as a dict; the last of a repeated name wins."""
    out = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name.strip():
            raise ConfigError(f"{what} {pair!r} must look like NAME=VALUE")
        out[name.strip()] = value.strip()
    return out


def model_sets(pairs: Iterable[str], what: str = "--set") -> dict[str, float]:
    """``NAME=VALUE`` model overrides: known parameter names and finite numbers (SI units)."""
    from ..model.params import PARAM_SPECS

    out = {}
    for name, text in key_values(pairs, what).items():
        if name not in PARAM_SPECS:
            raise ConfigError(f"{what} {name}={text}: unknown parameter {name!r}; known: {', '.join(PARAM_SPECS)}")
        try:
            value = float(text)
        except ValueError:
            raise ConfigError(f"{what} {name}={text!r}: value is not a number") from None
        if value != value or value in (float("inf"), float("-inf")):
            raise ConfigError(f"{what} {name}={text}: value is not finite")
        out[name] = value
    return out


def refuse_fixed(swept: str, fixed: dict[str, float], where: dict[str, str]) -> None:
    """Refuse a fixed value for the parameter being swept (it would be stored but never used)."""
    if swept in fixed:
        raise ConfigError(
            f"{where.get(swept, '--set ' + swept)}={fixed[swept]:g} fixes the swept parameter {swept!r}; "
            "drop it (the sweep's --from/--to set it)"
        )


def check_memory(needed: float, what: str) -> None:
    """Refuse (exit 2) work whose results need more memory [bytes] than this machine has, naming both."""
    from ..engine.scan import machine_memory

    memory = machine_memory()
    if needed > memory:
        raise ConfigError(
            f"{what} needs about {needed / 2**30:.3g} GiB of memory, more than this machine's "
            f"{memory / 2**30:.3g} GiB; make it shorter or coarser"
        )
