"""Declarative sweep definitions (TOML), e.g. ``sweeps/fig11a.toml``.

Top-level keys: ``parameter``, a range (``from``, ``to`` and ``step`` or
``points``; or an explicit ``values`` list), and optionally ``mode``,
``direction``, ``transient_periods``, ``record_periods``, ``initial``,
``kick``, ``rest_threshold``, ``starts``, ``seed``, ``output``, ``plot`` and
``description``. Tables: ``[model]`` (ModelParams overrides) and
``[backend]`` (``name`` plus that backend's options). Unknown keys are errors.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import ConfigError
from .sweep import SweepConfig, value_range

#: The repository's ``sweeps/`` folder (figures and benchmarks read the paper's sweeps from it).
SWEEPS_DIR = Path(__file__).resolve().parents[2] / "sweeps"

_SWEEP_KEYS = {
    "mode", "direction", "transient_periods", "record_periods", "initial",
    "kick", "rest_threshold", "starts", "seed",
}
_FILE_KEYS = {"parameter", "from", "to", "step", "points", "values", "output", "plot", "description", "model", "backend"}


@dataclass(frozen=True)
class SweepFile:
    """A loaded sweep definition: the configuration and where results go."""

    config: SweepConfig
    output: Path
    plot: Path | None
    description: str


def parse_sweep(data: dict[str, Any], source: str = "<sweep>") -> SweepFile:
    unknown = sorted(set(data) - _SWEEP_KEYS - _FILE_KEYS)
    if unknown:
        raise ConfigError(
            f"{source}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(_SWEEP_KEYS | _FILE_KEYS))}"
        )
    if "parameter" not in data:
        raise ConfigError(f"{source}: missing key 'parameter'")
    if "values" in data:
        if any(k in data for k in ("from", "to", "step", "points")):
            raise ConfigError(f"{source}: give either 'values' or a from/to range, not both")
        values = tuple(float(v) for v in data["values"])
    else:
        missing = [k for k in ("from", "to") if k not in data]
        if missing:
            raise ConfigError(f"{source}: missing key(s) {', '.join(missing)} (or give 'values')")
        values = tuple(value_range(float(data["from"]), float(data["to"]), data.get("step"), data.get("points")))
    backend = dict(data.get("backend", {}))
    if not isinstance(data.get("model", {}), dict) or not isinstance(backend, dict):
        raise ConfigError(f"{source}: [model] and [backend] must be tables")
    config = SweepConfig(
        parameter=data["parameter"],
        values=values,
        model=dict(data.get("model", {})),
        backend=backend.pop("name", "emulated"),
        backend_options=backend,
        **{k: data[k] for k in _SWEEP_KEYS if k in data},
    )
    output = Path(data.get("output", f"results/{data['parameter']}.parquet"))
    plot = Path(data["plot"]) if "plot" in data else None
    return SweepFile(config, output, plot, str(data.get("description", "")))


def load_sweep(path: Path) -> SweepFile:
    """Read and validate a TOML sweep definition."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise ConfigError(f"no sweep file at {str(path)!r}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    return parse_sweep(data, str(path))
