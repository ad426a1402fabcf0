"""A hybrid test's own logs read as measured records (format v1): a site log and a substructured trace.

A lab diagnoses the files its test wrote, under their own column names:

``pendsweep site -o LOG.parquet`` (metadata kind ``site-log``)
    One row per committed step of one client session: the command ``d``,
    the LVDT ``x_meas``, the encoder ``theta`` and the load cell ``Fs``. The
    numerical model ran in the client (OpenSees), so there is no ``Fe``: the
    record is of kind ``rig`` (the physical substructure under command), and
    a diagnosis covers the transfer system and the specimen.
``pendsweep trace OUT.parquet`` with ``--backend substructured`` (kind ``trace``)
    One row per controller tick: ``Fe``, the command, the LVDT, the encoder,
    the load cell, and the controller's own ``y`` (= y*, before the forward
    predictor) and ``F_fb`` (the force fed back, after any filter). A record
    of kind ``substructured`` with ``y_star`` and ``F_fb``.

The nominal model is the one the file was run with (its ``params``); the
nominal actuator is the configured one (``delay``: its transport delay;
``servo``: a second-order servo behind it; ``ideal``: no delay).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from ..errors import ConfigError, ParameterError
from ..model.params import ModelParams

#: Log columns -> record columns, per log kind.
RENAME = {
    "site-log": {"t": "t", "d": "y_cmd", "x_meas": "y", "theta": "theta", "Fs": "Fs"},
    "trace": {
        "t": "t", "Fe": "Fe", "command": "y_cmd", "x_meas": "y", "theta": "theta", "Fs": "Fs",
        "y": "y_star", "F_fb": "F_fb",
    },
}  # fmt: skip
#: Sensors behind the record columns of a log.
SENSORS = {
    "y": "LVDT (x_meas): quantised platform position with noise",
    "theta": "encoder (theta_x): quantised pendulum angle",
    "Fs": "load cell: tick-mean interface force with noise (and servo harmonics in a trace)",
    "y_cmd": "the command sent to the actuator",
}


def actuator_of(options: dict[str, Any]) -> tuple[dict[str, Any], float]:
    """The nominal actuator (metadata table) and delay [s] of a substructured backend's options."""
    kind = options.get("actuator", "ideal")
    delay = float(options.get("transport_delay", 0.0) or 0.0)
    if kind == "ideal":
        return {"model": "delay", "tau": 0.0}, 0.0
    if kind == "servo":
        rate = 2.0 * math.pi * float(options["servo_bandwidth"])
        zeta = float(options["servo_damping"])
        table = {"model": "second_order", "tau": delay, "rate": rate, "zeta": zeta}
        return table, delay + 2.0 * zeta / rate
    return {"model": "delay", "tau": delay}, delay


def record_of_log(data: pd.DataFrame, meta: dict[str, Any], name: str, session: int | None = None) -> dict[str, Any]:
    """The fields of the record of a site log or trace (module docstring), for :class:`pendsweep.measured.records.Record`.

    ``session``: a site log's client (default: the last).
    """
    kind = meta["kind"]
    if kind == "site-log":
        if data.empty:
            raise ConfigError(f"{name}: the site log holds no committed step")
        sessions = sorted(int(s) for s in pd.unique(data["session"]))
        chosen = sessions[-1] if session is None else int(session)
        if chosen not in sessions:
            raise ConfigError(f"{name}: the site log has sessions {sessions}; session {session} is not among them")
        data = data[data["session"] == chosen]
        config = meta.get("config") or {}
        params, options = config.get("params") or {}, config.get("rig") or {}
        record_kind, forcing = "rig", {}
    else:
        if meta.get("backend") != "substructured":
            raise ConfigError(f"{name}: a trace of the {meta.get('backend')!r} backend has no command or load cell; "
                              "only `pendsweep trace --backend substructured` traces are records")  # fmt: skip
        if int(meta.get("stride", 1)) != 1:
            raise ConfigError(f"{name}: written with --stride {meta['stride']}; a record needs every controller "
                              "tick (--stride 1)")  # fmt: skip
        params, options = meta.get("params") or {}, meta.get("backend_options") or {}
        record_kind = "substructured"
        forcing = {k: float(params[k]) for k in ("alpha", "fe") if k in params}
    rename = RENAME[kind]
    missing = [c for c in rename if c not in data.columns]
    if missing:
        raise ConfigError(f"{name}: the {kind} lacks column(s) {', '.join(missing)}")
    frame = pd.DataFrame({new: data[old].to_numpy(dtype=np.float64) for old, new in rename.items()})
    try:
        model = ModelParams.from_mapping(params)
    except (ParameterError, TypeError, ValueError) as exc:
        raise ConfigError(f"{name}: its params are not a model: {exc}") from None
    actuator, tau = actuator_of(options)
    sensors = {c: SENSORS[c] for c in SENSORS if c in frame.columns}
    return dict(data=frame, kind=record_kind, params=model, tau=tau, forcing=forcing, name=name,
                actuator=actuator, sensors=sensors)  # fmt: skip
