"""Declarative sweep definitions (TOML), e.g. the built-in ``fig11a``.

Top-level keys: ``parameter``, a range (``from``, ``to`` and ``step`` or
``points``; or an explicit ``values`` list), and optionally ``mode``,
``direction``, ``transient_periods``, ``record_periods``, ``initial``,
``kick``, ``rest_threshold``, ``starts``, ``seed``, ``output``, ``plot`` and
``description``. Tables: ``[model]`` (ModelParams overrides) and
``[backend]`` (``name`` plus that backend's options). Unknown keys, values of
the wrong type and keys that do not apply to the mode (``starts`` outside
multistart, ``direction`` and ``kick`` outside continue) are errors naming the
key and what it accepts.

The paper's sweeps live in the project's top-level ``sweeps/`` folder, where
users find, read and copy them; the package links to it
(``src/pendsweep/sweeps``) and the wheel ships the files (:data:`SWEEPS_DIR`),
so they run by name from any folder: ``pendsweep run fig11a``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ConfigError

#: The built-in sweep definitions, shipped as package data (``pendsweep run --list``): the top-level
#: ``sweeps/`` of a checkout (through the package's link), the files themselves in an installed wheel.
SWEEPS_DIR = Path(__file__).resolve().parents[1] / "sweeps"

#: Largest number of grid values a range may produce (a typo like ``step = 1e-300`` is refused, not allocated).
MAX_POINTS = 1_000_000
#: Largest transient or recorded forcing-period count per point.
MAX_PERIODS = 1_000_000
#: Largest number of multistart initial conditions per point.
MAX_STARTS = 100_000
#: Largest initial angle magnitude [rad]: five turns (sin and cos of larger floats lose digits; angles wrap anyway).
MAX_ANGLE = 10 * math.pi

_INT_KEYS = {"transient_periods": 0, "record_periods": 1, "starts": 1, "seed": 0, "points": 1}
_FLOAT_KEYS = {"from", "to", "step", "kick", "rest_threshold"}
_STR_KEYS = {"parameter", "mode", "direction", "output", "plot", "description"}
_SWEEP_KEYS = {
    "mode",
    "direction",
    "transient_periods",
    "record_periods",
    "initial",
    "kick",
    "rest_threshold",
    "starts",
    "seed",
}
_FILE_KEYS = {
    "parameter",
    "from",
    "to",
    "step",
    "points",
    "values",
    "output",
    "plot",
    "description",
    "model",
    "backend",
}


@dataclass(frozen=True)
class SweepFile:
    """A loaded sweep definition: the configuration and where results go."""

    config: Any  # pendsweep.studies.sweep.SweepConfig (imported lazily: it pulls in the kernels)
    output: Path
    plot: Path | None
    description: str


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _number(source: str, key: str, v: Any) -> float:
    if not _is_number(v) or not math.isfinite(v):
        raise ConfigError(f"{source}: {key} = {v!r} must be a finite number")
    return float(v)


def check_types(data: dict[str, Any], source: str) -> None:
    """Raise :class:`ConfigError` naming the first key whose value has the wrong type."""
    for key, lo in _INT_KEYS.items():
        if key in data:
            v = data[key]
            if not isinstance(v, int) or isinstance(v, bool) or v < lo:
                raise ConfigError(f"{source}: {key} = {v!r} must be an integer >= {lo}")
    if data.get("seed", 0) >= 2**63:
        raise ConfigError(f"{source}: seed = {data['seed']!r} must be below 2**63")
    for key in _FLOAT_KEYS & set(data):
        _number(source, key, data[key])
    for key in _STR_KEYS & set(data):
        if not isinstance(data[key], str):
            raise ConfigError(f"{source}: {key} = {data[key]!r} must be a string")
    if "values" in data:
        v = data["values"]
        if not isinstance(v, list) or not v:
            raise ConfigError(f"{source}: values = {v!r} must be a non-empty list of numbers")
        for x in v:
            _number(source, "values", x)
    if "initial" in data:
        v = data["initial"]
        if not isinstance(v, list) or len(v) != 4:
            raise ConfigError(
                f"{source}: initial = {v!r} must be a list of 4 numbers [y m, ydot m/s, theta rad, thetadot rad/s]"
            )
        for x in v:
            _number(source, "initial", x)
    bounds = {  # the command line's bounds (pendsweep.cli._app), so a file cannot do what an option may not
        "transient_periods": (0, MAX_PERIODS, ""),
        "record_periods": (1, MAX_PERIODS, ""),
        "starts": (1, MAX_STARTS, ""),
        "kick": (0.0, math.pi, " rad"),
        "rest_threshold": (0.0, math.pi, " rad"),
    }
    for key, (lo, hi, unit) in bounds.items():
        if key in data and not lo <= data[key] <= hi:
            raise ConfigError(
                f"{source}: {key} = {data[key]!r}{unit} is outside the accepted range [{lo:g}, {hi:g}]{unit}"
            )
    if "initial" in data:
        y, ydot, theta, thetadot = data["initial"]
        for what, v, limit, unit in (("y", y, 10.0, "m"), ("ydot", ydot, 1e3, "m/s"),
                                     ("theta", theta, MAX_ANGLE, "rad"), ("thetadot", thetadot, 1e3, "rad/s")):  # fmt: skip
            if abs(v) > limit:
                raise ConfigError(
                    f"{source}: initial {what} = {v!r} {unit} is outside the accepted range [-{limit:g}, {limit:g}] {unit}"
                )
    for table in ("model", "backend"):
        if table in data and not isinstance(data[table], dict):
            raise ConfigError(f"{source}: [{table}] must be a table, not {data[table]!r}")
    for name, v in data.get("model", {}).items():
        _number(source, f"model.{name}", v)
    for name, v in data.get("backend", {}).items():
        if name == "name":
            if not isinstance(v, str):
                raise ConfigError(f"{source}: backend.name = {v!r} must be a string")
        elif not (_is_number(v) or isinstance(v, (str, bool))):
            raise ConfigError(f"{source}: backend.{name} = {v!r} must be a number, a string or a boolean")
    for key in ("output",):
        if key in data and not data[key].endswith(".parquet"):
            raise ConfigError(f"{source}: output = {data[key]!r} must end in .parquet")
    if "plot" in data and Path(data["plot"]).suffix.lower() not in {".png", ".pdf", ".svg"}:
        raise ConfigError(f"{source}: plot = {data['plot']!r} must end in .png, .pdf or .svg")


def describe_count(count: float) -> str:
    """``"100,000,001 values"``, or ``"more than 1,000,000 values"`` for counts too large to spell out."""
    return f"{int(count):,} values" if count < 1e15 else f"more than {MAX_POINTS:,} values"


def grid_size(start: float, stop: float, step: float) -> float:
    """Number of values ``value_range(start, stop, step)`` would produce (as a float: it may be huge)."""
    ratio = (stop - start) / step if step != 0 else math.inf
    return math.floor(ratio + 1e-9) + 1 if math.isfinite(ratio) else math.inf


def parse_sweep(data: dict[str, Any], source: str = "<sweep>") -> SweepFile:
    """Validate a parsed sweep definition and build its :class:`SweepFile`."""
    from .sweep import SweepConfig, value_range

    unknown = sorted(set(data) - _SWEEP_KEYS - _FILE_KEYS)
    if unknown:
        raise ConfigError(
            f"{source}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(_SWEEP_KEYS | _FILE_KEYS))}"
        )
    if "parameter" not in data:
        raise ConfigError(f"{source}: missing key 'parameter'")
    check_types(data, source)
    mode = data.get("mode", "continue")
    if "starts" in data and mode != "multistart":
        raise ConfigError(
            f'{source}: starts = {data["starts"]!r} applies only to mode = "multistart" (mode is {mode!r})'
        )
    for key in ("direction", "kick"):
        if key in data and mode != "continue":
            raise ConfigError(f'{source}: {key} = {data[key]!r} applies only to mode = "continue" (mode is {mode!r})')
    if "values" in data:
        if any(k in data for k in ("from", "to", "step", "points")):
            raise ConfigError(f"{source}: give either 'values' or a from/to range, not both")
        values = tuple(float(v) for v in data["values"])
    else:
        missing = [k for k in ("from", "to") if k not in data]
        if missing:
            raise ConfigError(f"{source}: missing key(s) {', '.join(missing)} (or give 'values')")
        if "step" in data and "points" in data:
            raise ConfigError(f"{source}: give either 'step' or 'points', not both")
        start, stop = float(data["from"]), float(data["to"])
        step = data.get("step")
        count = grid_size(start, stop, float(step)) if step else 0
        if count > MAX_POINTS:  # step 0 is refused by value_range
            raise ConfigError(
                f"{source}: step = {step!r} gives {describe_count(count)} from {start:g} to {stop:g}; at most {MAX_POINTS:,}"
            )
        if data.get("points", 0) > MAX_POINTS:
            raise ConfigError(f"{source}: points = {data['points']!r} must be at most {MAX_POINTS}")
        values = tuple(value_range(start, stop, step, data.get("points")))
    model = dict(data.get("model", {}))
    parameter = data["parameter"]
    if parameter in model:
        raise ConfigError(
            f"{source}: model.{parameter} = {model[parameter]!r} is the swept parameter; remove it from [model]"
        )
    backend = dict(data.get("backend", {}))
    config = SweepConfig(
        parameter=parameter,
        values=values,
        model=model,
        backend=backend.pop("name", "emulated"),
        backend_options=backend,
        **{k: data[k] for k in _SWEEP_KEYS if k in data},
    )
    output = Path(data.get("output", f"results/{parameter}.parquet"))
    plot = Path(data["plot"]) if "plot" in data else None
    return SweepFile(config, output, plot, str(data.get("description", "")))


def builtin_sweeps() -> dict[str, Path]:
    """Name -> path of every sweep definition shipped with the package."""
    return {p.stem: p for p in sorted(SWEEPS_DIR.glob("*.toml"))}


def resolve_sweep(definition: str | Path) -> Path:
    """A sweep file path, or the built-in definition called ``definition`` (e.g. ``fig11a``)."""
    path = Path(definition)
    if path.exists():
        return path
    builtin = builtin_sweeps()
    name = path.name[: -len(".toml")] if path.name.endswith(".toml") else path.name
    if str(path.parent) == "." and name in builtin:
        return builtin[name]
    raise ConfigError(
        f"no sweep file at {str(definition)!r} and no built-in sweep of that name; built-in: {', '.join(builtin)}"
    )


def load_sweep(path: str | Path) -> SweepFile:
    """Read and validate a TOML sweep definition (a path or a built-in name)."""
    import tomllib  # here, not at the top: the command line imports this module's limits, and tomllib is 1.8 ms of it

    path = resolve_sweep(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except IsADirectoryError:
        raise ConfigError(f"{str(path)!r} is a directory, not a sweep file") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{str(path)!r} is not a text (UTF-8) TOML file") from None
    except OSError as exc:
        raise ConfigError(f"cannot read sweep file {str(path)!r}: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    return parse_sweep(data, str(path))
