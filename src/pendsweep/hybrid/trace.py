"""Time-series runs of any backend and the trace files of ``pendsweep trace``."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pandas as pd

from .._version import __version__
from ..backends import Backend
from ..engine.results import atomic_write_table, check_writable, read_results, with_metadata
from ..errors import ResultsError
from ..model.params import ModelParams


def run_trace(
    backend: Backend,
    params: ModelParams,
    initial: tuple[float, float, float, float] = (0.0, 0.0, 0.1, 0.0),
    transient_periods: int = 100,
    periods: int = 20,
    stride: int = 1,
) -> pd.DataFrame:
    """Trace ``periods`` forcing periods after ``transient_periods`` from ``initial``.

    ``initial`` is ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])``; the
    returned time ``t`` [s] starts at 0 at the end of the transient. When the
    transient does not end OK the trace is empty and ``attrs["status"]`` says why.
    """
    backend.validate(params)
    state = backend.initial_state(params, *initial)
    if transient_periods > 0:
        run = backend.run_point(params, state, transient_periods, 0)
        if run.status.value != "ok":
            df = pd.DataFrame(columns=["t", "y", "ydot", "theta", "thetadot"])
            df.attrs["status"] = run.status.value
            return df
        state = run.state
    df = backend.trace(params, state, periods, stride)
    df.attrs.setdefault("status", "ok")
    return df


def write_trace(df: pd.DataFrame, path: Path, metadata: dict[str, Any]) -> None:
    """Write a trace parquet atomically with ``metadata`` (kind ``trace``)."""
    path = Path(path)
    check_writable(path)
    meta = {"kind": "trace", "package_version": __version__, "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    meta.update(metadata)
    atomic_write_table(with_metadata(df, meta), path)


def read_trace(path: Path, session: int | None = None) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read a trace written by :func:`write_trace`, or a ``pendsweep site`` log as one.

    A site log's command ``d`` is the target ``y`` (= y*) and its LVDT
    reading ``x_meas`` the achieved displacement; ``session`` picks one client
    (default: the last). Its metadata then says backend ``substructured``.
    """
    df, meta = read_results(path)
    if meta.get("kind") == "site-log":
        if df.empty:
            raise ResultsError(f"site log {str(path)!r} holds no committed step")
        sessions = sorted(int(k) for k in df["session"].unique())
        chosen = sessions[-1] if session is None else session
        if chosen not in sessions:
            raise ResultsError(f"site log {str(path)!r} has sessions {sessions}; session {session} is not among them")
        df = df[df["session"] == chosen].rename(columns={"d": "y"}).reset_index(drop=True)
        return df, meta | {"backend": "substructured", "session": int(chosen)}
    if meta.get("kind") != "trace":
        raise ResultsError(
            f"{str(path)!r} is a {meta.get('kind', 'unknown')!r} file, not a trace from `pendsweep trace`"
        )
    return df, meta
