"""The log of an experimental site: one row per committed step, parquet with the site's configuration.

Columns (SI):

============  ======  ===============================================================
column        unit    meaning
============  ======  ===============================================================
session               client index, 0 for the first client served
step                  committed step within the session (1 = the first)
t             s       simulated time of the step (the client's clock)
d, v, a       m, m/s, the command of the step's last trial (displacement, velocity,
              m/s^2   acceleration as the client sent them)
x             m       true platform position
x_meas        m       LVDT reading
xdot          m/s     platform velocity
xddot_mean    m/s^2   platform's mean acceleration over the step
theta         rad     encoder angle theta_x (quantised)
theta_true    rad     true pendulum angle
thetadot      rad/s   pendulum rate
Fs            N       load-cell reading (the interface force, Eq. (4), with noise)
Fs_true       N       the same without noise
force         N       the force returned by getForce (``Fs`` less the reported mass's
                      inertia, see ``report_mass``)
service_time  s       trial received to force sent, less the real-time hold (NaN: the
                      client asked no force)
wall          s       wall time of the trial since the session began
late                  the force went out more than one step after its time (real time)
============  ======  ===============================================================

The file is rewritten whole and atomically after every session and when the
site stops (never half-written); the metadata (kind ``site-log``) holds the
full configuration, one summary per session, with its end reason, and the
clients refused by the allow-list (``refused``: peer, time, reason, the first
:data:`MAX_REFUSALS_KEPT` of them; ``refused_total`` counts them all).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from .rig import READING_INDEX, SiteRig

LOG_COLUMNS = (
    "session", "step", "t", "d", "v", "a", "x", "x_meas", "xdot", "xddot_mean", "theta", "theta_true",
    "thetadot", "Fs", "Fs_true", "force", "service_time", "wall", "late",
)  # fmt: skip
#: Rows per allocation of the in-memory log.
LOG_CHUNK = 8192
#: Refused clients kept one by one in the metadata; later ones are only counted, so that a flood of
#: connections from outside the allow-list cannot grow the site's memory without bound.
MAX_REFUSALS_KEPT = 1000
_READINGS = ("x", "x_meas", "xdot", "xddot_mean", "theta", "theta_true", "thetadot", "Fs", "Fs_true")
_READING_AT = np.array([READING_INDEX[name] for name in _READINGS])


class SiteLog:
    """Rows of committed steps, kept in memory and written to ``path`` (None: not written).

    Parameters
    ----------
    path : Path or None
    config : dict
        The site's full configuration, stored in the metadata.
    """

    def __init__(self, path: Path | None, config: dict[str, Any]) -> None:
        self.path = Path(path) if path is not None else None
        self.config = config
        self._chunks: list[np.ndarray] = []
        self.n_rows = 0
        self.sessions: list[dict[str, Any]] = []
        self.refused: list[dict[str, str]] = []
        self.refused_total = 0
        self.session = -1
        self.session_start = 0.0
        self._step = 0

    def start_session(self) -> None:
        self.session += 1
        self._step = 0
        self.session_start = time.perf_counter()

    def append(self, rig: SiteRig, service: float, wall: float, late: bool) -> None:
        """One row for the step ``rig`` has just committed."""
        self._step += 1
        at = self.n_rows % LOG_CHUNK
        if at == 0:  # a new chunk, never a copy of the old ones: no stall in a real-time test
            self._chunks.append(np.empty((LOG_CHUNK, len(LOG_COLUMNS))))
        row = self._chunks[-1][at]
        row[0], row[1], row[2] = self.session, self._step, rig.committed_time
        row[3:6] = rig.trial_command
        row[6:15] = rig.committed_readings[_READING_AT]
        row[15], row[16], row[17], row[18] = rig.force(), service, wall, late
        self.n_rows += 1

    def end_session(self, summary) -> None:
        self.sessions.append(summary.to_dict())

    def refuse(self, peer: str, reason: str) -> None:
        """Keep one client refused at connect (called from the site's accepting thread, never a session's)."""
        self.refused_total += 1
        if len(self.refused) < MAX_REFUSALS_KEPT:
            self.refused.append({"peer": peer, "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "reason": reason})

    def columns(self) -> dict[str, np.ndarray]:
        data = np.concatenate(self._chunks)[: self.n_rows] if self._chunks else np.empty((0, len(LOG_COLUMNS)))
        out = {name: np.ascontiguousarray(data[:, i]) for i, name in enumerate(LOG_COLUMNS)}
        out["session"] = out["session"].astype(np.int32)
        out["step"] = out["step"].astype(np.int64)
        out["late"] = out["late"].astype(bool)
        return out

    def write(self) -> None:
        """Write every row so far, atomically (nothing when the log has no path)."""
        if self.path is None:
            return
        from .._version import __version__
        from ..engine.columns import table
        from ..engine.results import atomic_write_table, with_metadata

        meta = {
            "kind": "site-log",
            "config": self.config,
            "sessions": self.sessions,
            "refused": list(self.refused),  # a copy: the accepting thread may append while this is written
            "refused_total": self.refused_total,
            "package_version": __version__,
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        }
        atomic_write_table(with_metadata(table(self.columns()), meta), self.path)
