"""A site's log read back as a hybrid bifurcation diagram: the sweep's rows of a test that any client drove.

A client such as OpenSees (``examples/opensees_alpha_sweep.py``) steps a
parameter of its numerical model through one session of a ``pendsweep
site``; only the site's log (:mod:`.log`) knows what the pendulum did.
Given the schedule the client ran (the values, in order, each for
``transient + record`` forcing periods of ``steps`` committed steps),
:func:`sweep_rows` cuts the log into forcing periods and builds the per-period
records of :data:`pendsweep.kernels.RECORD_COLUMNS` from the committed
steps: the platform command ``d`` as the oscillator's ``y`` (the client's
displacement), its velocity ``v``, the encoder ``theta`` and the rate
``thetadot``; a period ends at forcing phase 0, its last step being the
section. Each value's record is classified as the site's sensors demand
(noisy records, :mod:`pendsweep.analysis.sections`; nothing can be re-simulated, so
an undecided record is ``transient``). :func:`write_sweep_rows` writes them
as a sweep result (kind ``sweep``) that ``pendsweep plot`` and
``pendsweep plot --compare``-style overlays read.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ..analysis.classify import classify_records
from ..analysis.sections import section_scales
from ..backends.status import Status
from ..errors import ConfigError, ResultsError
from ..kernels import RECORD_COLUMNS
from ..kernels._layout import RECORD_INDEX
from ..model.params import ENCODER_RESOLUTION, ModelParams


def read_site_log(path: Path, wait: float = 0.0) -> pa.Table:
    """A site's log, waiting up to ``wait`` seconds for it to appear (a site writes it when its client has left)."""
    deadline = time.monotonic() + wait
    while not Path(path).is_file() and time.monotonic() < deadline:
        time.sleep(0.05)
    try:
        return pq.read_table(path)
    except OSError as exc:
        raise ResultsError(f"cannot read the site log {str(path)!r}: {exc}") from None


def _records_of(theta, thetadot, y, ydot) -> np.ndarray:
    """Per-period records (k, 8) of per-step arrays shaped (k periods, steps)."""
    wrapped = theta - 2.0 * math.pi * np.ceil((theta - math.pi) / (2.0 * math.pi))
    largest = np.argmax(np.abs(wrapped), axis=1)
    rows = np.arange(theta.shape[0])
    turns = np.ceil((theta[:, -1] - math.pi) / (2.0 * math.pi)) - np.ceil((theta[:, 0] - math.pi) / (2.0 * math.pi))
    out = np.empty((theta.shape[0], len(RECORD_COLUMNS)))
    for name, values in {
        "theta_peak": wrapped[rows, largest],
        "theta_absmax": np.abs(wrapped).max(axis=1),
        "y_sec": y[:, -1],
        "ydot_sec": ydot[:, -1],
        "theta_sec": wrapped[:, -1],
        "thetadot_sec": thetadot[:, -1],
        "y_absmax": np.abs(y).max(axis=1),
        "rotations": turns,
    }.items():
        out[:, RECORD_INDEX[name]] = values
    return out


def sweep_rows(
    log: pa.Table,
    parameter: str,
    values: list[float],
    fe: float,
    steps: int,
    transient: int,
    record: int,
    model: dict[str, float] | None = None,
    rest_threshold: float = ENCODER_RESOLUTION,
    session: int | None = None,
) -> pa.Table:
    """The sweep's long-form rows of a site log (module docstring); one row per recorded period.

    Parameters
    ----------
    log : pyarrow.Table
        A ``pendsweep site`` log (:class:`~.log.SiteLog` columns).
    parameter : str
        The stepped parameter's name (its column).
    values : list of float
        The values in the order the client ran them.
    fe : float
        Forcing frequency [Hz] (for the section's normalisation).
    steps : int
        Committed steps per forcing period.
    transient, record : int
        Forcing periods per value left to decay, then recorded.
    model : dict, optional
        The model's other parameters (for the section's scales).
    session : int, optional
        The client session (default: the last).

    Returns
    -------
    pyarrow.Table
        Sweep rows (README "Results files"): direction ``up``, every whole value
        the log holds; a value the log ends inside is left out.
    """
    sessions = log["session"].to_numpy()
    if not len(sessions):
        raise ConfigError("the site log holds no committed step")
    chosen = int(sessions.max()) if session is None else int(session)
    mask = sessions == chosen
    columns = {name: log[name].to_numpy()[mask] for name in ("d", "v", "theta", "thetadot")}
    per_value = (transient + record) * steps
    whole = min(len(values), len(columns["d"]) // per_value)
    base = ModelParams.from_mapping({**(model or {}), "fe": fe})
    tables = []
    for i in range(whole):
        tail = slice(i * per_value + transient * steps, (i + 1) * per_value)
        shaped = {k: v[tail].reshape(record, steps) for k, v in columns.items()}
        records = _records_of(shaped["theta"], shaped["thetadot"], shaped["d"], shaped["v"])
        params = base.replace(**{parameter: values[i]})
        motion = classify_records(records, section_scales(records, params), Status.OK, None, rest_threshold, noisy=True)
        table = {parameter: np.full(record, values[i]), "direction": ["up"] * record, "point": np.full(record, i),
                 "start": np.zeros(record, dtype=np.int64), "period": np.arange(record)}  # fmt: skip
        table |= {name: records[:, j] for j, name in enumerate(RECORD_COLUMNS)}
        table["rotations"] = records[:, RECORD_INDEX["rotations"]].astype(np.int64)
        table |= {"kicked": np.zeros(record, dtype=bool), "status": ["ok"] * record, "motion": [motion.label] * record}
        noise = motion.noise
        table["section_noise"] = np.full(record, noise.largest_jitter if noise else math.nan)
        table["periodic_tol"] = np.full(record, noise.applied_tolerance if noise else math.nan)
        tables.append(pa.table(table))
    if not tables:
        raise ConfigError(f"the site log holds {len(columns['d'])} steps: less than one value's {per_value}")
    return pa.concat_tables(tables)


def write_sweep_rows(rows: pa.Table, path: Path, config: dict[str, Any], source: str) -> Path:
    """Write ``rows`` as a sweep result (kind ``sweep``; ``config`` as a sweep's, ``source`` saying who drove the rig)."""
    from ..engine.results import atomic_write_table, run_metadata, with_metadata

    meta = run_metadata("sweep", config, backend=config.get("backend", ""), source=source)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_table(with_metadata(rows, meta), path)
    return path


__all__ = ["read_site_log", "sweep_rows", "write_sweep_rows"]
