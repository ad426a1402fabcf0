"""Measured-data format v1: reader, writer and validation.

A record is a uniformly sampled table with SI columns

``t`` [s], ``theta`` [rad] (pendulum angle from the hanging equilibrium),
``y`` [m] (pivot/oscillator displacement; the measured actuator displacement
x in a substructured test), ``Fe`` [N] (external force on the (emulated)
oscillator), and optionally ``y_cmd`` [m] (actuator command) and ``Fs`` [N]
(measured interface force). A ``free_decay`` record needs only ``t, theta``.

Metadata (kind, nominal params, optional forcing, actuator and DAQ sampling ``daq``) sits in a sidecar
``NAME.json`` next to ``NAME.csv``, or in the parquet key-value metadata under
the key ``pendsweep``. :func:`read_free_swing` reads the raw encoder format of
``shared/data/measured/free-swing-rotary-pendulum``.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ..engine.results import atomic_write_table, read_metadata, with_metadata
from ..errors import ConfigError, ParameterError, ResultsError
from ..model.params import ModelParams

FORMAT_VERSION = 1
KINDS = ("free_decay", "forced", "substructured", "rig")
#: Required columns per kind. ``rig``: the physical substructure under command without the
#: numerical model's force (an experimental site's log).
REQUIRED = {
    "free_decay": ("t", "theta"),
    "forced": ("t", "theta", "y", "Fe"),
    "substructured": ("t", "theta", "y", "Fe", "y_cmd"),
    "rig": ("t", "theta", "y", "y_cmd", "Fs"),
}
#: Every column the format knows, with its SI unit.
UNITS = {
    "t": "s", "theta": "rad", "y": "m", "Fe": "N", "y_cmd": "m", "Fs": "N",
    "y_star": "m", "F_fb": "N", "ydot": "m/s", "yddot": "m/s^2",
}  # fmt: skip
#: What each column measures (written into a record's metadata with its unit).
DESCRIPTIONS = {
    "t": "sample time",
    "theta": "pendulum angle from the hanging equilibrium (encoder)",
    "y": "oscillator / platform displacement (substructured: the actuator's LVDT)",
    "Fe": "external force on the (emulated) oscillator",
    "y_cmd": "actuator command (the controller's output)",
    "Fs": "interface force (load cell)",
    "y_star": "numerical model's displacement y* before any forward prediction",
    "F_fb": "force fed back to the numerical model (after any filter)",
    "ydot": "measured platform velocity",
    "yddot": "measured platform acceleration (accelerometer)",
}
#: Units a record may declare per column (``columns.NAME.unit``), as factors to the SI unit.
UNIT_FACTORS = {
    "s": {"s": 1.0, "ms": 1e-3},
    "rad": {"rad": 1.0, "deg": math.pi / 180.0, "mrad": 1e-3},
    "m": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "cm": 1e-2, "in": 0.0254},
    "N": {"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605},
    "m/s": {"m/s": 1.0, "mm/s": 1e-3},
    "m/s^2": {"m/s^2": 1.0, "mm/s^2": 1e-3, "g": 9.80665},
}
#: The DAQ's sampling a record may declare (metadata ``daq``), accepted values first the default:
#: ``load_cell`` averaged over the controller's tick or sampled at it; ``command`` reaching the
#: actuator smooth (the replay's cubic Hermite of the samples), ramped linearly between ticks or held.
DAQ_KEYS = {"load_cell": ("tick_mean", "point"), "command": ("smooth", "ramped", "held")}
#: Metadata params that are not ModelParams fields.
EXTRA_PARAMS = ("tau",)
#: Parquet files of this package that are records under other column names (:mod:`pendsweep.measured.logs`).
LOG_KINDS = ("site-log", "trace")
#: Relative tolerance on the sample step for a "uniformly sampled" record.
UNIFORM_RTOL = 1e-3


@dataclass
class Record:
    """One measured record.

    Attributes
    ----------
    data : DataFrame
        Columns of :data:`UNITS` (at least those of ``REQUIRED[kind]``), float64.
    kind : str
        One of :data:`KINDS`.
    params : ModelParams
        The user's nominal model (package defaults for missing keys).
    tau : float
        Nominal actuator delay [s] (substructured records).
    forcing : dict
        Optional ``{"alpha": N, "fe": Hz}``.
    name : str
        Where the record came from.
    actuator : dict
        Optional nominal actuator model (``{"model": "second_order", "tau": s,
        "rate": rad/s, "zeta": -}``, see :func:`pendsweep.measured.diagnose.identify.transfer.nominal_actuator`);
        empty: a pure delay of ``tau``.
    sensors : dict
        Optional description of each column's sensor (free text), kept in the metadata.
    daq : dict
        Optional DAQ sampling (``{"load_cell": "tick_mean" | "point", "command": "smooth" |
        "ramped" | "held"}``, :data:`DAQ_KEYS`); missing keys take their defaults (:meth:`sampling`).
    """

    data: pd.DataFrame
    kind: str
    params: ModelParams = field(default_factory=ModelParams)
    tau: float = 0.0
    forcing: dict[str, float] = field(default_factory=dict)
    name: str = "record"
    actuator: dict[str, Any] = field(default_factory=dict)
    sensors: dict[str, str] = field(default_factory=dict)
    daq: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        validate(self.data, self.kind, self.name)
        self.daq = _parse_daq(self.daq, self.name)

    def sampling(self, key: str) -> str:
        """The DAQ's ``load_cell`` or ``command`` sampling, declared or the default (:data:`DAQ_KEYS`)."""
        return self.daq.get(key, DAQ_KEYS[key][0])

    @property
    def t(self) -> np.ndarray:
        return self.data["t"].to_numpy()

    @property
    def dt(self) -> float:
        """Sample step [s]."""
        t = self.t
        return float((t[-1] - t[0]) / (len(t) - 1))

    def channel(self, name: str) -> np.ndarray:
        return np.ascontiguousarray(self.data[name].to_numpy(), dtype=np.float64)

    def metadata(self) -> dict[str, Any]:
        params = self.params.to_dict()
        if self.kind in ("substructured", "rig"):
            params["tau"] = self.tau
        meta: dict[str, Any] = {"format": FORMAT_VERSION, "kind": self.kind, "params": params}
        if self.forcing:
            meta["forcing"] = dict(self.forcing)
        if self.actuator:
            meta["actuator"] = dict(self.actuator)
        if self.daq:
            meta["daq"] = dict(self.daq)
        meta["columns"] = {
            c: {
                "unit": UNITS[c],
                "description": DESCRIPTIONS[c],
                **({"sensor": self.sensors[c]} if c in self.sensors else {}),
            }
            for c in UNITS
            if c in self.data.columns
        }
        return meta


def validate(data: pd.DataFrame, kind: str, name: str = "record") -> None:
    """Raise :class:`ConfigError` unless ``data`` is a valid record of ``kind``."""
    if kind not in KINDS:
        raise ConfigError(f"{name}: unknown kind {kind!r}; accepted kinds: {', '.join(KINDS)}")
    missing = [c for c in REQUIRED[kind] if c not in data.columns]
    if missing:
        raise ConfigError(
            f"{name}: missing column(s) {', '.join(missing)} for kind {kind!r}; required: {', '.join(REQUIRED[kind])}"
        )
    if len(data) < 3:
        raise ConfigError(f"{name}: {len(data)} samples; a record needs at least 3")
    for col in data.columns:
        if col not in UNITS:
            continue
        try:
            values = data[col].to_numpy(dtype=np.float64)
        except (TypeError, ValueError):
            raise ConfigError(f"{name}: column {col!r} holds non-numeric values") from None
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.argmax(bad))
            raise ConfigError(
                f"{name}: column {col!r} has {int(bad.sum())} NaN/inf value(s), first at row {i}; "
                "all values must be finite"
            )
    t = data["t"].to_numpy(dtype=np.float64)
    step = np.diff(t)
    if (step <= 0).any():
        i = int(np.argmax(step <= 0))
        raise ConfigError(f"{name}: time is not strictly increasing at row {i + 1} (t = {t[i]:g} then {t[i + 1]:g} s)")
    mean = (t[-1] - t[0]) / (len(t) - 1)
    worst = float(np.max(np.abs(step - mean)))
    if worst > UNIFORM_RTOL * mean:
        i = int(np.argmax(np.abs(step - mean)))
        raise ConfigError(
            f"{name}: time is not uniformly sampled: step {step[i]:g} s at row {i + 1} differs from the "
            f"mean step {mean:g} s by more than {UNIFORM_RTOL:g} of it"
        )


#: Actuator models a record's metadata may name, with their parameters.
ACTUATOR_MODELS = {
    "delay": ("tau", "gain"),
    "first_order": ("tau", "gain", "rate"),
    "second_order": ("tau", "gain", "rate", "zeta"),
}


def _parse_actuator(table: Any, name: str) -> dict[str, Any]:
    """The metadata's ``actuator`` table, checked: a known model and finite numbers >= 0 for its parameters."""
    if table is None:
        return {}
    if not isinstance(table, dict):
        raise ConfigError(f"{name}: metadata 'actuator' must be a JSON object, got {table!r}")
    model = table.get("model", "delay")
    if model not in ACTUATOR_MODELS:
        raise ConfigError(f"{name}: actuator model {model!r} is unknown; accepted: {', '.join(ACTUATOR_MODELS)}")
    out: dict[str, Any] = {"model": model}
    for k, v in table.items():
        if k == "model":
            continue
        if k not in ACTUATOR_MODELS[model]:
            raise ConfigError(
                f"{name}: actuator.{k} does not belong to model {model!r} ({', '.join(ACTUATOR_MODELS[model])})"
            )
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0):
            raise ConfigError(f"{name}: actuator.{k} = {v!r} must be a finite number >= 0")
        out[k] = float(v)
    if "rate" in ACTUATOR_MODELS[model] and not out.get("rate", 0.0) > 0:
        raise ConfigError(f"{name}: actuator model {model!r} needs rate > 0 (1/T [1/s] or ws [rad/s])")
    return out


def _parse_daq(table: Any, name: str) -> dict[str, str]:
    """The metadata's ``daq`` table, checked: known keys with one of their accepted values (:data:`DAQ_KEYS`)."""
    if table is None:
        return {}
    if not isinstance(table, dict):
        raise ConfigError(f"{name}: metadata 'daq' must be a JSON object, got {table!r}")
    for k, v in table.items():
        if k not in DAQ_KEYS:
            raise ConfigError(f"{name}: unknown daq key {k!r}; accepted: {', '.join(DAQ_KEYS)}")
        if v not in DAQ_KEYS[k]:
            raise ConfigError(f"{name}: daq.{k} = {v!r}; accepted: {', '.join(DAQ_KEYS[k])}")
    return dict(table)


def _parse_columns(table: Any, data: pd.DataFrame, name: str) -> dict[str, str]:
    """Convert columns declared in other units to SI (``columns.NAME.unit``); return the sensor descriptions."""
    if table is None:
        return {}
    if not isinstance(table, dict):
        raise ConfigError(f"{name}: metadata 'columns' must be a JSON object, got {table!r}")
    sensors = {}
    for col, spec in table.items():
        if col not in UNITS:
            continue  # a column the format does not use: kept in the file, ignored here
        if not isinstance(spec, dict):
            raise ConfigError(f"{name}: metadata columns.{col} must be a JSON object with 'unit', got {spec!r}")
        unit = spec.get("unit", UNITS[col])
        factors = UNIT_FACTORS[UNITS[col]]
        if unit not in factors:
            raise ConfigError(f"{name}: column {col!r} in unit {unit!r}; accepted: {', '.join(factors)}")
        if factors[unit] != 1.0 and col in data.columns:
            data[col] = data[col].to_numpy(dtype=np.float64) * factors[unit]
        if isinstance(spec.get("sensor"), str):
            sensors[col] = spec["sensor"]
    return sensors


def _parse_metadata(meta: Any, name: str) -> tuple[str, ModelParams, float, dict[str, float]]:
    if not isinstance(meta, dict):
        raise ConfigError(f"{name}: metadata must be a JSON object, got {type(meta).__name__}")
    if "kind" not in meta:
        raise ConfigError(f"{name}: metadata has no 'kind'; accepted kinds: {', '.join(KINDS)}")
    kind = meta["kind"]
    if kind not in KINDS:
        raise ConfigError(f"{name}: unknown kind {kind!r}; accepted kinds: {', '.join(KINDS)}")
    raw = dict(_numbers(meta.get("params") or {}, "params", name))
    tau = raw.pop("tau", 0.0)
    if not (math.isfinite(tau) and tau >= 0):
        raise ConfigError(f"{name}: tau = {tau!r} s must be finite and >= 0")
    try:
        params = ModelParams.from_mapping(raw)
    except ParameterError as exc:
        raise ConfigError(f"{name}: {exc}") from None
    if kind in ("substructured", "rig") and not (params.M > params.M2 and params.C >= params.C2):
        raise ConfigError(
            f"{name}: params M = {params.M:g} kg, C = {params.C:g} kg/s must exceed the platform's M2 = "
            f"{params.M2:g} kg, C2 = {params.C2:g} kg/s (the numerical model's M1 = M - M2 > 0, C1 = C - C2 >= 0)"
        )
    forcing = _numbers(meta.get("forcing") or {}, "forcing", name)
    unknown = set(forcing) - {"alpha", "fe"}
    if unknown:
        raise ConfigError(f"{name}: unknown forcing key(s) {', '.join(sorted(unknown))}; accepted: alpha, fe")
    return kind, params, tau, forcing


def _numbers(table: Any, key: str, name: str) -> dict[str, float]:
    """A metadata table of finite numbers (``params``, ``forcing``); anything else is a ConfigError naming it."""
    if not isinstance(table, dict):
        raise ConfigError(f"{name}: metadata {key!r} must be a JSON object of numbers, got {table!r}")
    for k, v in table.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"{name}: metadata {key}.{k} = {v!r} must be a finite number")
    return {k: float(v) for k, v in table.items()}


def _mismatched_csv(path: Path) -> None:
    """Raise if a CSV row has a different number of fields than the header."""
    with open(path) as fh:
        header = fh.readline().count(",")
        for i, line in enumerate(fh, start=2):
            if line.strip() and line.count(",") != header:
                raise ConfigError(
                    f"{str(path)!r}: mismatched lengths: line {i} has {line.count(',') + 1} fields, "
                    f"the header has {header + 1}"
                )


def read_record(path: str | Path, session: int | None = None) -> Record:
    """Read a format-v1 record (``.csv`` + ``.json`` sidecar, or ``.parquet``).

    Files in the raw free-swing format (first line ``trigger_start_deg, ...``)
    are read with :func:`read_free_swing`; a ``pendsweep site`` log or a
    substructured ``pendsweep trace`` as the record they hold
    (:mod:`pendsweep.measured.logs`; ``session`` picks a site log's client, default
    the last). Columns declared in other units (metadata ``columns.NAME.unit``,
    e.g. ``mm``, ``deg``, ``kN``) are converted to SI. Raises
    :class:`ConfigError` for an invalid record and :class:`ResultsError` for
    an unreadable file.
    """
    path = Path(path)
    if not path.is_file():
        raise ResultsError(f"no record file at {str(path)!r}")
    name = str(path)
    if path.suffix == ".parquet":
        try:
            meta = read_metadata(path)
        except ValueError as exc:  # metadata that is not JSON
            raise ConfigError(f"{name!r}: its pendsweep metadata is not valid JSON ({exc})") from None
        try:
            data = pq.read_table(path).to_pandas()
        except (OSError, pa.ArrowInvalid) as exc:
            raise ResultsError(f"cannot read {name!r} as parquet: {exc}") from None
    else:
        try:
            path.read_bytes().decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ConfigError(
                f"{name!r} is not a text (UTF-8) file: byte {exc.start} is {exc.object[exc.start]:#04x}"
            ) from None
        with open(path) as fh:
            first = fh.readline()
        if first.startswith("trigger_start_deg"):
            return read_free_swing(path)
        if not first.strip():
            raise ConfigError(f"{name!r} is empty or has no header line; a record CSV starts with its column names")
        sidecar = path.with_suffix(".json")
        if not sidecar.is_file():
            raise ConfigError(f"{name!r} has no metadata sidecar {str(sidecar)!r}")
        try:
            meta = json.loads(sidecar.read_bytes().decode("utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ConfigError(f"{str(sidecar)!r} is not valid JSON: {exc}") from None
        _mismatched_csv(path)
        try:
            data = pd.read_csv(path)
        except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
            raise ConfigError(f"cannot parse {name!r} as CSV: {exc}") from None
    if isinstance(meta, dict) and meta.get("kind") in LOG_KINDS:
        from .logs import record_of_log  # a test's own log (site log, trace): its columns renamed

        return Record(**record_of_log(data, meta, name, session))
    kind, params, tau, forcing = _parse_metadata(meta, name)
    validate(data, kind, name)  # before the float cast, so that text in a column is named, not a traceback
    data = data.astype({c: np.float64 for c in data.columns if c in UNITS})
    sensors = _parse_columns(meta.get("columns"), data, name)
    actuator = _parse_actuator(meta.get("actuator"), name)
    daq = _parse_daq(meta.get("daq"), name)
    return Record(data, kind, params, tau, forcing, name, actuator, sensors, daq)


def write_record(record: Record, path: str | Path) -> list[Path]:
    """Write ``record`` as ``.parquet`` or as ``.csv`` plus a ``.json`` sidecar.

    Returns the files written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    cols = [c for c in UNITS if c in record.data.columns]
    data = record.data[cols]
    if path.suffix == ".parquet":
        atomic_write_table(with_metadata(data, record.metadata()), path)
        return [path]
    if path.suffix != ".csv":
        raise ConfigError(f"record path {str(path)!r} must end in .csv or .parquet")
    sidecar = path.with_suffix(".json")
    data.to_csv(path, index=False, float_format="%.10g")
    sidecar.write_text(json.dumps(record.metadata(), indent=1, sort_keys=True))
    return [path, sidecar]


FREE_SWING_DIR = Path("shared/data/measured/free-swing-rotary-pendulum")
#: Environment variable naming the shared data folder (the one holding ``measured/``), for installed packages.
DATA_ENV = "PENDSWEEP_DATA"


def find_free_swing_data() -> Path | None:
    """The shared real free-swing records, or None.

    Looked up in ``$PENDSWEEP_DATA/measured/free-swing-rotary-pendulum``, then
    as ``shared/data/measured/...`` in the current folder or an ancestor of it
    (a wheel install run from a checkout), then in an ancestor of this package
    (a source checkout).
    """
    env = os.environ.get(DATA_ENV)
    if env:
        candidate = Path(env) / FREE_SWING_DIR.relative_to("shared/data")
        return candidate if candidate.is_dir() else None
    cwd = Path.cwd().resolve()
    for parent in (cwd, *cwd.parents, *Path(__file__).resolve().parents):
        if (parent / FREE_SWING_DIR).is_dir():
            return parent / FREE_SWING_DIR
    return None


def read_free_swing(path: str | Path) -> Record:
    """Read a raw free-swing file (degrees, one sample a line, 3-value header).

    Line 1 names ``trigger_start_deg, sample_rate, duration_sec``, line 2 gives
    them, then one angle in degrees per line. The angle is converted to rad
    and ``t`` starts at 0. Offset and release velocity are left to the fits.
    """
    path = Path(path)
    name = str(path)
    try:
        with open(path) as fh:
            header = [h.strip() for h in fh.readline().split(",")]
            values = [float(v) for v in fh.readline().split(",")]
            angles = np.array([float(line) for line in fh if line.strip()], dtype=np.float64)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{name!r} is not a raw free-swing file: {exc}") from None
    if header[:2] != ["trigger_start_deg", "sample_rate"] or len(values) < 2:
        raise ConfigError(f"{name!r}: expected header 'trigger_start_deg, sample_rate, duration_sec'")
    rate = values[1]
    if not (math.isfinite(rate) and rate > 0):
        raise ConfigError(f"{name!r}: sample_rate = {rate!r} must be a positive number [Hz]")
    data = pd.DataFrame({"t": np.arange(len(angles)) / rate, "theta": np.deg2rad(angles)})
    return Record(data, "free_decay", ModelParams(), name=name)
