"""The delay-tolerance curve: how far the hybrid test's delay moves a bifurcation of the emulated system.

A bifurcation of the emulated system (a ``continue`` result, e.g. the
semi-trivial solution's period doubling at 16.097 N) is found again in the
hybrid loop (:mod:`.loop`) at the shortest transport delay, by Newton on the
curve's defining system (:mod:`.curve_system`) from the emulated orbit, then
solved at every delay of a grid (``--delay-step``, warm-started from the
points before), for each prediction order. The prediction horizon stays
matched to the loop's total effective delay (``tau_hat = None``) as the
delay grows.

Why a grid and not arclength steps: the loop is continuous but only
piecewise smooth in the delay. Where the delay is a whole number of ticks,
the held command's switch crosses a sampling instant of the load cell, and
the bifurcation's slope against the delay jumps (docs/continuation.md); a
grid resolves that within-tick ripple evenly, and each point is an
independent Newton solve.

Result (``kind = "tolerance"``): one row per delay and order, with
``order``, ``transport_delay`` [s], ``effective_delay`` [s] (transport,
hold and servo lag at the forcing frequency, what the predictor
compensates), the bifurcation's value, ``shift`` (relative to the emulated
value), ``others_max`` (the largest modulus among the orbit's *other*
multipliers), ``unstable_others`` (how many of them lie outside the unit
circle) and ``loop_stable`` (no more than the emulated orbit has at its
bifurcation: the hybrid loop adds no instability of its own; otherwise no
test could hold the rig on this orbit),
with the curve's other columns (:mod:`.curve_run`). The metadata's
``limits`` give, per order, the largest transport delay up to which
``|shift| <= within`` holds on a stable loop from the shortest delay on
(linear interpolation between points; ``null`` when even the shortest
delay fails), ``intervals`` every such span of delays (a bifurcation may
come back into tolerance at longer delays), and ``ends`` why each order's
grid stopped. Each order's
grid is also kept beside the result (``STEM.order-K.parquet``),
checkpointed after every point and resumable.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ...engine.results import atomic_write_table, run_metadata, with_metadata
from ...errors import ConfigError, PendsweepError
from ...model.loop import MAX_PREDICTOR_ORDER
from .curve_run import CurveConfig, _default_limits, checked_bifurcation
from .curve_system import CURVE_KINDS, CurveEnded, initial_reference, other_multipliers
from .problem import ContinuationError, EvaluationFailed
from .run import ContinuationConfig, parameter_unit, read_json, stored_config

#: Why a delay's point may not be found: Newton does not converge, the orbit cannot be integrated (an
#: unstable loop trips), the critical multiplier changes type, or the linear algebra fails.
_POINT_FAILURES = (ContinuationError, EvaluationFailed, PendsweepError, CurveEnded, np.linalg.LinAlgError)

#: Options the tolerance study sets itself.
STUDIED_OPTIONS = ("transport_delay", "predictor_order", "tau_hat")


@dataclass(frozen=True)
class ToleranceConfig:
    """A delay-tolerance study (stored with its result).

    Attributes
    ----------
    continuation : dict
        The emulated continuation's ``config``.
    bifurcation : dict
        The emulated bifurcation (type, value, period, section).
    delays : (float, float)
        Transport delays [s] the curves cover.
    within : float
        Relative tolerance on the bifurcation's value.
    orders : tuple of int
        Prediction orders (-1: none).
    backend_options : dict
        The loop's other options.
    """

    continuation: dict[str, Any]
    bifurcation: dict[str, Any]
    delays: tuple[float, float]
    within: float = 0.01
    orders: tuple[int, ...] = (-1, 1, 2)
    backend_options: dict[str, Any] = field(default_factory=dict)
    delay_step: float = 2.5e-4
    newton_tol: float = 1e-9
    source: str = ""

    def __post_init__(self) -> None:
        lo, hi = self.delays
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi <= 1.0):
            raise ConfigError(f"--delay-from {lo!r} / --delay-to {hi!r} must satisfy 0 <= from < to <= 1 [s]")
        if not (math.isfinite(self.delay_step) and 1e-6 <= self.delay_step <= hi - lo):
            raise ConfigError(f"--delay-step {self.delay_step!r} must be in [1e-6, delay-to - delay-from] [s]")
        if not (math.isfinite(self.within) and 0 < self.within < 1):
            raise ConfigError(f"--within {self.within!r} must be in (0, 1) (0.01: 1 %)")
        bad = [k for k in self.orders if not -1 <= k <= MAX_PREDICTOR_ORDER]
        if not self.orders or bad:
            raise ConfigError(f"--orders: {bad[0] if bad else 'none'}; accepted -1 (none) to {MAX_PREDICTOR_ORDER}")
        if len(set(self.orders)) != len(self.orders):
            raise ConfigError(f"--orders {','.join(map(str, self.orders))}: each order once")
        if "dt" in self.backend_options:
            raise ConfigError("-B dt: the controller step is START's (`continue --dt`); continue again at another step")
        fixed = sorted(set(self.backend_options) & set(STUDIED_OPTIONS))
        if fixed:
            raise ConfigError(f"-B {fixed[0]}: the study sets it (--delay-from/--delay-to, --orders; matched horizon)")
        for order in self.orders:
            self.curve_config(order)  # refuses bad backend options before any run (exit 2)

    @classmethod
    def from_file(cls, path: Path, bifurcation: int, **options: Any) -> ToleranceConfig:
        doc = read_json(path)
        cfg = stored_config(doc, path)
        if cfg.get("backend", "emulated") != "emulated":
            raise ConfigError(f"{str(path)!r} continues the hybrid loop; give an emulated `continue` result")
        bifs = doc.get("bifurcations", [])
        if not isinstance(bifs, list) or not 0 <= bifurcation < len(bifs):
            raise ConfigError(f"--bifurcation {bifurcation}: {str(path)!r} has {len(bifs)} bifurcation(s)")
        bif = checked_bifurcation(bifs[bifurcation], path)
        if bif.get("type") not in CURVE_KINDS:
            raise ConfigError(
                f"bifurcation {bifurcation} of {str(path)!r} is a {bif.get('type')!r} point without an orbit to "
                "trace; choose a fold, period doubling or Neimark-Sacker point (or run `continue` again)"
            )
        return cls(continuation=cfg, bifurcation=bif, source=str(path), **options)

    @property
    def parameter(self) -> str:
        return self.continuation["parameter"]

    def loop_continuation(self, order: int) -> ContinuationConfig:
        """The hybrid loop's continuation configuration for prediction ``order`` at the shortest delay."""
        cfg = self.continuation
        model = {k: v for k, v in cfg["model"].items() if k not in ("M1", "C1")}
        options = dict(self.backend_options) | {"predictor_order": order, "transport_delay": self.delays[0]}
        return ContinuationConfig(
            parameter=self.parameter, start=cfg["start"], stop=cfg["stop"], model=model, eps=cfg["eps"], dt=cfg["dt"],
            backend="substructured", backend_options=options,
        )  # fmt: skip

    def curve_config(self, order: int) -> CurveConfig:
        loop = self.loop_continuation(order)
        return CurveConfig(
            continuation=loop.to_dict(), bifurcation=self.bifurcation, second="transport_delay", start=self.delays[0],
            stop=self.delays[1], first_limits=_default_limits(self.continuation), newton_tol=self.newton_tol,
            source=self.source,
        )  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["delays"], d["orders"] = list(self.delays), list(self.orders)
        return d


def order_path(output: Path, order: int) -> Path:
    """Where prediction ``order``'s delay grid is kept beside ``output``."""
    name = "none" if order < 0 else str(order)
    return Path(output).with_name(f"{Path(output).stem}.order-{name}.parquet")


def within_limit(delays: np.ndarray, shifts: np.ndarray, within: float, ok: np.ndarray | None = None) -> float | None:
    """Largest delay up to which ``|shift| <= within`` (and ``ok``) holds from the first point on.

    ``delays`` ascend from the shortest delay; between the last point inside
    and the first outside the shift is interpolated linearly (a point that
    fails ``ok``, the loop's own stability, ends the range at the point
    before it). None when even the first point is outside.
    """
    ok = np.ones(delays.size, dtype=bool) if ok is None else np.asarray(ok, dtype=bool)
    spans = within_spans(delays, shifts, within, ok)
    return spans[0][1] if spans and spans[0][0] == float(delays[0]) else None


def within_spans(delays: np.ndarray, shifts: np.ndarray, within: float, ok: np.ndarray) -> list[tuple[float, float]]:
    """Every interval of delays [s] where ``|shift| <= within`` on a stable loop (``ok``), ends interpolated.

    A span entered or left between two points of which one fails ``ok`` ends at the stable point.
    """
    inside = (np.abs(shifts) <= within) & np.asarray(ok, dtype=bool)
    spans, start = [], None

    def crossing(i: int) -> float:  # where |shift| crosses ``within`` between points i and i + 1
        a, b = abs(shifts[i]), abs(shifts[i + 1])
        if not (ok[i] and ok[i + 1]) or a == b:
            return float(delays[i] if inside[i] else delays[i + 1])
        return float(delays[i] + (within - a) / (b - a) * (delays[i + 1] - delays[i]))

    for i in range(delays.size):
        if inside[i] and start is None:
            start = float(delays[0]) if i == 0 else crossing(i - 1)
        if start is not None and (i == delays.size - 1 or not inside[i + 1]):
            spans.append((start, float(delays[i]) if i == delays.size - 1 else crossing(i)))
            start = None
    return spans


def delay_grid(config: ToleranceConfig) -> np.ndarray:
    """The transport delays [s] each order's bifurcation is solved at: ``--delay-from`` to ``--delay-to`` by ``--delay-step``."""
    lo, hi = config.delays
    n = int(math.floor((hi - lo) / config.delay_step + 1e-9))
    grid = lo + config.delay_step * np.arange(n + 1)
    return grid if grid[-1] >= hi - 1e-12 else np.append(grid, hi)


def trace_order(
    config: ToleranceConfig, order: int, output: Path, progress: bool, resume: bool
) -> tuple[pd.DataFrame, str]:
    """The bifurcation at every delay of :func:`delay_grid` for prediction ``order``; its rows and why it ended.

    Each point is Newton on the curve's defining system at that fixed delay,
    warm-started by linear extrapolation from the two before (the first
    from the emulated orbit, :meth:`~.curves.CurveContinuation.find_start`).
    A fixed delay grid, not arclength steps: the loop is only piecewise
    smooth in the delay (docs/continuation.md), and a grid resolves its
    within-tick ripple evenly. Rows are checkpointed to ``output`` after
    every point; ``resume`` goes on after the last stored delay.
    """
    from ...engine.results import read_results
    from ...engine.scan import progress_bar
    from .curve_run import _row
    from .curves import CurveContinuation

    curve_config = config.curve_config(order)
    cp = curve_config.curve_problem()
    cc = CurveContinuation(
        cp, curve_config.first_limits, config.delays, curve_config.settings(), (config.parameter, "transport_delay")
    )
    meta = run_metadata("tolerance-order", config.to_dict() | {"order": order})
    rows: list[dict[str, Any]] = []
    if resume and Path(output).exists():
        stored, stored_meta = read_results(output)
        if stored_meta.get("config_hash") == meta["config_hash"]:
            if stored_meta.get("end"):
                return stored, stored_meta["end"]
            rows = stored.to_dict("records")
    grid = delay_grid(config)
    bif = config.bifurcation
    emulated = np.array([complex(*m) for m in bif.get("multipliers", [])])
    reference_unstable = 0
    if emulated.size:
        critical = initial_reference(bif["type"], emulated)
        reference_unstable = int(np.sum(np.abs(other_multipliers(emulated, critical, bif["type"])) > 1.0))
    bar = progress_bar(progress, total=grid.size, unit="delay", desc=f"order {order}")
    bar.update(len(rows))
    end = "range"
    try:
        for tau in grid[len(rows) :]:
            try:
                point = _solve_at(cc, cp, curve_config, rows, float(tau))
            except _POINT_FAILURES as exc:  # the grid of this order ends here, with its reason
                end = f"no convergence at {1e3 * tau:.3g} ms ({exc.__class__.__name__})"
                break
            row = _row(len(rows), point, 1, cp, curve_config)
            others = other_multipliers(point.multipliers, point.critical, curve_config.kind)
            row["others_max"] = float(np.abs(others).max())
            row["unstable_others"] = int(np.sum(np.abs(others) > 1.0))
            # The loop is stable when its orbit has no unstable multiplier the emulated orbit lacks: the
            # rotation is itself unstable at its fold (a complex pair outside), the semi-trivial PD is not.
            row["loop_stable"] = bool(row["unstable_others"] <= reference_unstable)
            rows.append(row)
            atomic_write_table(with_metadata(pd.DataFrame(rows), meta | {"end": ""}), output)
            bar.update(1)
    finally:
        bar.close()
    frame = pd.DataFrame(rows)
    atomic_write_table(with_metadata(frame, meta | {"end": end}), output)
    return frame, end


def _solve_at(cc, cp, curve_config, rows, tau: float):
    """The bifurcation at delay ``tau``, warm-started from the points (or stored rows) before it."""
    if not rows:
        from .curve_run import _start_state

        bif = curve_config.bifurcation
        mu = np.array([complex(*m) for m in bif.get("multipliers", [])])
        return cc.find_start(_start_state(cp, bif), float(bif["value"]), tau, initial_reference(curve_config.kind, mu))
    last = rows[-1]
    x1 = np.array(last["u"][: cp.n]) * cp.scale
    lam1, critical = float(last[curve_config.first]), complex(last["critical_re"], last["critical_im"])
    x, lam = x1, lam1
    if len(rows) >= 2:
        before = rows[-2]
        x0 = np.array(before["u"][: cp.n]) * cp.scale
        t = (tau - last["transport_delay"]) / (last["transport_delay"] - before["transport_delay"])
        x, lam = x1 + t * (x1 - x0), lam1 + t * (lam1 - float(before[curve_config.first]))
    try:
        return cc.start(x, lam, tau, critical)
    except _POINT_FAILURES:  # the extrapolation overshot (a kink at a whole tick): from the last point itself
        return cc.start(x1, lam1, tau, critical)


def run_tolerance(
    config: ToleranceConfig, output: Path, progress: bool = False, resume: bool = False
) -> dict[str, Any]:
    """Solve every order's bifurcation over the delay grid, write the summary ``output``; its lines and limits."""
    from ...backends import make_backend
    from ...model.params import ModelParams

    reference = float(config.bifurcation["value"])
    unit = parameter_unit(config.parameter)
    fe = ModelParams.from_mapping(config.continuation["model"]).fe
    frames, limits, intervals, ends, lines = [], {}, {}, {}, []
    kind = config.bifurcation["type"]
    lines.append(f"emulated {kind} at {config.parameter} = {reference:.6g} {unit}")
    for order in config.orders:
        rows, end = trace_order(config, order, order_path(output, order), progress, resume)
        name = "no prediction" if order < 0 else f"prediction order {order}"
        ends[str(order)] = end
        if rows.empty:
            limits[str(order)] = None
            lines.append(f"{name}: the {kind} was not found in the loop ({end})")
            continue
        backend = make_backend("substructured", **(config.backend_options | {"predictor_order": order}))
        rows = rows.assign(
            order=order,
            shift=rows[config.parameter] / reference - 1.0,
            effective_delay=[
                dataclasses.replace(backend, transport_delay=float(t)).effective_delay(fe)
                for t in rows["transport_delay"]
            ],
        )
        frames.append(rows)
        delays = rows["transport_delay"].to_numpy()
        limit = within_limit(delays, rows["shift"].to_numpy(), config.within, rows["loop_stable"].to_numpy())
        limits[str(order)] = limit
        first = rows.iloc[0]
        text = (
            f"{name}: {kind} at {first[config.parameter]:.6g} {unit} ({100 * first['shift']:+.2f} %) at "
            f"{1e3 * first['transport_delay']:g} ms transport delay; "
        )
        unstable = rows[~rows["loop_stable"]]
        if limit is None:
            text += (
                f"already beyond {100 * config.within:g} % there"
                if first["loop_stable"]
                else "the loop is unstable there"
            )
        else:
            at = float(np.interp(limit, delays, rows["effective_delay"]))
            covered = limit >= delays[-1] - 1e-12
            text += f"within {100 * config.within:g} % {'at every delay to' if covered else 'up to'} {1e3 * limit:.2f} ms ({1e3 * at:.2f} ms effective at {fe:g} Hz)"
        spans = within_spans(delays, rows["shift"].to_numpy(), config.within, rows["loop_stable"].to_numpy())
        intervals[str(order)] = spans
        later = [(a, b) for a, b in spans if limit is None or a > limit + 1e-12]
        if later:
            text += "; within it again for " + ", ".join(f"{1e3 * a:.2f}-{1e3 * b:.2f} ms" for a, b in later)
        if not unstable.empty:
            text += f"; the loop itself is unstable from {1e3 * unstable['transport_delay'].iloc[0]:.3g} ms"
        if end != "range":
            text += f"; stopped: {end}"
        lines.append(text)
    summary = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    summary = summary.drop(columns=[c for c in ("u", "tangent", "vector", "step", "march") if c in summary])
    meta = run_metadata(
        "tolerance", config.to_dict(), limits=limits, intervals=intervals, ends=ends, reference=reference
    )
    atomic_write_table(with_metadata(summary, meta), output)
    return {"lines": lines, "limits": limits, "rows": summary}
