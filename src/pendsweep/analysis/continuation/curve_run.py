"""``pendsweep curve``: a bifurcation of a continuation traced in a second parameter, and its result file.

The result is a parquet file, one row per curve point in arclength order
(the start's far side first), with the configuration in its metadata like
every other result (``kind = "curve"``):

=================================  ==========================================================
column                             meaning
=================================  ==========================================================
``point``                          index along the curve
``march``                          -1 behind the start, 0 the start, +1 ahead (towards ``--to``)
``<first>``, ``<second>``          both parameters [their units]
``omega_hat``                      ``w_e / (2 w_p)`` at the point (Fig. 10's abscissa)
``y_sec`` ... ``thetadot_sec``     the orbit's section at forcing phase 0 [m, m/s, rad, rad/s]
``theta_absmax``, ``y_absmax``     the orbit's largest |theta| [rad] and |y| [m] over its k periods
``critical_re``, ``critical_im``   the critical Floquet multiplier
``max_multiplier``                 largest modulus of the others' and the critical one
``normal_form``                    fold ``a`` or period-doubling ``c`` (NaN on NS curves)
``kappa``                          ``cos(arg mu)`` of the critical multiplier (NS: its angle)
``event``                          a located codimension-two point or turn ("" otherwise)
``multipliers_re/_im``             all Floquet multipliers
``u``, ``tangent``, ``vector``,    the scaled unknowns, tangent, critical eigenvector and next
``step``                           arclength step (what a resumed march goes on from)
=================================  ==========================================================

The metadata's ``ends`` says why each end stopped; ``complete`` is false
while a run is under way: the file is rewritten atomically every
:data:`CHECKPOINT_POINTS` points, and ``--resume`` continues each
unfinished end from its last point.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ...engine.results import atomic_write_table, check_writable, read_results, run_metadata, with_metadata
from ...errors import ConfigError
from ...model.params import PARAM_SPECS, ModelParams, check_value
from .curve_system import CURVE_KINDS, CurveProblem, initial_reference
from .curves import CurveContinuation, CurvePoint, curve_settings
from .loop import LOOP_PARAMETERS
from .problem import Settings
from .run import MODEL_CONTINUABLE, read_json, stored_config, stored_problem

#: Points between two checkpoints of the result file.
CHECKPOINT_POINTS = 10


@dataclass(frozen=True)
class CurveConfig:
    """A two-parameter curve run; stored in full with its result.

    Attributes
    ----------
    continuation : dict
        The continuation document's ``config`` (model, backend, step, smoothing).
    bifurcation : dict
        The started-from bifurcation of that document (type, value, period, section/state).
    second : str
        The second parameter (a model parameter, or a loop option for the hybrid loop).
    start, stop : float
        Interval of the second parameter; ``start <= value <= stop`` either way round.
    first_limits : (float, float)
        Interval the first parameter may cover [its unit].
    ds, ds_max : float
        First and largest arclength step (scaled).
    max_points : int
        Points per direction.
    newton_tol : float
        Newton tolerance (scaled max-norm).
    """

    continuation: dict[str, Any]
    bifurcation: dict[str, Any]
    second: str
    start: float
    stop: float
    first_limits: tuple[float, float]
    ds: float = 0.02
    ds_max: float = 0.1
    max_points: int = 200
    newton_tol: float = 1e-9
    source: str = ""
    second_value: float = field(init=False, default=math.nan)

    def __post_init__(self) -> None:
        first = self.first
        loop = self.continuation.get("backend", "emulated") != "emulated"
        allowed = MODEL_CONTINUABLE + (tuple(LOOP_PARAMETERS) if loop else ())
        if self.second not in allowed:
            raise ConfigError(
                f"--second {self.second!r}: choose one of {', '.join(allowed)}"
                + ("" if loop else " (loop options need a continuation with --backend substructured)")
            )
        if self.second == first:
            raise ConfigError(f"--second {self.second} is the continuation's own parameter; give another one")
        if self.bifurcation.get("type") not in CURVE_KINDS:
            raise ConfigError(
                f"a {self.bifurcation.get('type')!r} point cannot be traced; choose a fold, period doubling or "
                "Neimark-Sacker point (pendsweep continue lists them)"
            )
        for v in (self.start, self.stop):
            if not math.isfinite(v):
                raise ConfigError(f"--from/--to {v!r} must be finite")
            if self.second in PARAM_SPECS:
                check_value(self.second, v)
            elif v < 0:
                raise ConfigError(f"--from/--to {v!r} of {self.second} must be >= 0 [{LOOP_PARAMETERS[self.second]}]")
        if self.start == self.stop:
            raise ConfigError(f"--from and --to are both {self.start:g}: give an interval of {self.second}")
        value = self._second_at_start()
        lo, hi = sorted((self.start, self.stop))
        if not lo <= value <= hi:
            raise ConfigError(
                f"the bifurcation was found at {self.second} = {value:g}, outside --from/--to [{lo:g}, {hi:g}]"
            )
        object.__setattr__(self, "second_value", value)
        a, b = self.first_limits
        if not (math.isfinite(a) and math.isfinite(b) and a < b and a <= self.bifurcation["value"] <= b):
            raise ConfigError(
                f"--limits {a:g} {b:g} must be an interval of {first} holding the bifurcation at "
                f"{self.bifurcation['value']:g}"
            )
        checks = (
            ("ds", 0 < self.ds <= 1, "in (0, 1]"),
            ("ds_max", self.ds <= self.ds_max <= 1, "in [ds, 1]"),
            ("max_points", self.max_points >= 1, "an integer >= 1"),
            ("newton_tol", 1e-13 <= self.newton_tol <= 1e-4, "in [1e-13, 1e-4]"),
        )
        for name, ok, accepted in checks:
            if not ok:
                raise ConfigError(f"{name} = {getattr(self, name)!r} must be {accepted}")

    @property
    def first(self) -> str:
        return self.continuation["parameter"]

    @property
    def kind(self) -> str:
        return self.bifurcation["type"]

    def _second_at_start(self) -> float:
        cfg = self.continuation
        if self.second in LOOP_PARAMETERS:
            value = cfg["backend_options"].get(self.second)
            if value is None:
                raise ConfigError(f"{self.second} is matched (None) in the continuation: set it with -B to trace it")
            return float(value)
        return float(ModelParams.from_mapping(cfg["model"]).to_dict()[self.second])

    def curve_problem(self) -> CurveProblem:
        doc = {"config": self.continuation}
        n_cmd = None
        if self.second == "transport_delay":
            from ...backends import make_backend

            options = self.continuation["backend_options"] | {"transport_delay": max(self.start, self.stop)}
            n_cmd = make_backend("substructured", **options).n_cmd
        problem = stored_problem(doc, int(self.bifurcation["period"]), n_cmd)
        return CurveProblem(problem, self.second, self.kind, abs(self.stop - self.start))

    def settings(self) -> Settings:
        return curve_settings(ds=self.ds, ds_max=self.ds_max, max_points=self.max_points, newton_tol=self.newton_tol)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["first"] = self.first
        d["first_limits"] = list(self.first_limits)
        d["kind"] = self.kind
        return d


def config_from_file(path: Path, bifurcation: int, **options: Any) -> CurveConfig:
    """A :class:`CurveConfig` starting from bifurcation number ``bifurcation`` of continuation file ``path``."""
    doc = read_json(path)
    cfg = stored_config(doc, path)
    bifs = doc.get("bifurcations", [])
    if not isinstance(bifs, list):
        raise ConfigError(f"{str(path)!r}: its bifurcations are not a list")
    traceable = [i for i, b in enumerate(bifs) if b.get("type") in CURVE_KINDS]
    if not bifs or not 0 <= bifurcation < len(bifs):
        raise ConfigError(
            f"--bifurcation {bifurcation}: {str(path)!r} has {len(bifs)} bifurcation(s)"
            + (f"; traceable: {', '.join(map(str, traceable))}" if traceable else "")
        )
    bif = checked_bifurcation(bifs[bifurcation], path)
    limits = options.pop("first_limits", None) or _default_limits(cfg)
    return CurveConfig(continuation=cfg, bifurcation=bif, first_limits=tuple(limits), source=str(path), **options)


def checked_bifurcation(bif: Any, path: Path) -> dict[str, Any]:
    """A stored bifurcation with a finite value, an integer period and its orbit (ConfigError otherwise)."""

    def numbers(v: Any, size: int | None) -> bool:
        ok = isinstance(v, list) and all(isinstance(e, (int, float)) and math.isfinite(e) for e in v)
        return ok and (size is None or len(v) == size)

    if not isinstance(bif, dict) or "section" not in bif:
        raise ConfigError(f"{str(path)!r} was written before bifurcations carried their orbit: run `continue` again")
    value, period = bif.get("value"), bif.get("period")
    if not (isinstance(value, (int, float)) and math.isfinite(value)):
        raise ConfigError(f"{str(path)!r}: bifurcation value {value!r} is not a finite number")
    if not (isinstance(period, int) and period >= 1):
        raise ConfigError(f"{str(path)!r}: bifurcation period {period!r} is not an integer >= 1")
    if not numbers(bif["section"], 4) or ("state" in bif and not numbers(bif["state"], None)):
        raise ConfigError(f"{str(path)!r}: a bifurcation's section must be 4 finite numbers (its state finite numbers)")
    if not numbers([c for m in bif.get("multipliers", []) for c in (m if isinstance(m, list) else [None])], None):
        raise ConfigError(f"{str(path)!r}: a bifurcation's multipliers must be [re, im] pairs of finite numbers")
    return bif


def _default_limits(cfg: dict[str, Any]) -> tuple[float, float]:
    """The continuation's interval widened by its length on each side (kept in the parameter's range)."""
    lo, hi = sorted((cfg["start"], cfg["stop"]))
    width = hi - lo
    lo, hi = lo - width, hi + width
    name = cfg["parameter"]
    if name in PARAM_SPECS:
        spec = PARAM_SPECS[name]
        lo, hi = max(lo, spec.lower), min(hi, spec.upper)
    else:
        lo = max(lo, 0.0)
    return lo, hi


# -- running ------------------------------------------------------------------------------
def run_curve(config: CurveConfig, output: Path, progress: bool = False, resume: bool = False) -> pd.DataFrame:
    """Trace the curve of ``config``, writing ``output`` (checkpoints, resume); return its rows."""
    from ...engine.scan import progress_bar

    check_writable(output)
    cp = config.curve_problem()
    names = (config.first, config.second)
    done = _resumable(output, config) if resume else None
    bar = progress_bar(progress, unit="pt", desc=f"curve {config.kind} in ({config.first}, {config.second})")
    continuation = CurveContinuation(
        cp, config.first_limits, (config.start, config.stop), config.settings(), names, progress=bar.update
    )
    state = {"back": [], "ahead": [], "ends": ["", ""], "start": None, "last": time.monotonic()}

    def checkpoint(force: bool = False) -> None:
        pending = len(state["back"]) + len(state["ahead"])
        if force or pending % CHECKPOINT_POINTS == 0 or time.monotonic() - state["last"] > 5.0:
            _write(output, config, cp, state)
            state["last"] = time.monotonic()

    try:
        if done is not None and done["complete"]:
            return done["rows"]
        if done is not None:
            state.update(start=done["start"], back=done["back"], ahead=done["ahead"], ends=done["ends"])
        else:
            bif = config.bifurcation
            x0 = _start_state(cp, bif)
            mu = np.array([complex(*m) for m in bif.get("multipliers", [])])
            state["start"] = continuation.find_start(x0, float(bif["value"]), config.second_value,
                                                initial_reference(config.kind, mu))  # fmt: skip
        for index, key in ((1, "ahead"), (0, "back")):
            if state["ends"][index]:
                continue
            origin = _origin(continuation, state, key)

            def keep(point: CurvePoint, key=key) -> None:
                state[key].append(point)
                checkpoint()

            _, end = continuation.march(origin, on_point=keep, budget=config.max_points - len(state[key]))
            state["ends"][index] = end
    finally:
        bar.close()
    checkpoint(force=True)
    rows, _ = read_results(output)
    return rows


def _start_state(cp: CurveProblem, bif: dict[str, Any]) -> np.ndarray:
    """The start's continued state: the stored one, or the loop at rest on the section (a longer delay line).

    A delay line lengthened for a curve into longer delays (or an emulated
    start in the loop) has no stored state of its size; the loop's state
    consistent with the section is then Newton's start.
    """
    state = np.array(bif.get("state", bif["section"]), dtype=float)
    if state.size == cp.n:
        return state
    return cp.problem.from_section(np.array(bif["section"], dtype=float))


def _origin(continuation: CurveContinuation, state: dict[str, Any], key: str) -> CurvePoint:
    """Where the march ``key`` goes on from: its last point, or the start (reversed behind it).

    A point read back from a resumed file is recomputed from its stored unknowns and tangent.
    """

    def restored(row: Any) -> CurvePoint:
        if isinstance(row, CurvePoint):
            return row
        return continuation.restore(row["u"], np.array(row["tangent"]), complex(row["critical_re"], row["critical_im"]),
                                    np.array(row["vector"]), float(row["step"]))  # fmt: skip

    if state[key]:
        return restored(state[key][-1])
    state["start"] = restored(state["start"])
    return state["start"] if key == "ahead" else continuation.reverse(state["start"])


def _write(output: Path, config: CurveConfig, cp: CurveProblem, state: dict[str, Any]) -> None:
    points = [(p, -1) for p in state["back"][::-1]] + [(state["start"], 0)] + [(p, 1) for p in state["ahead"]]
    rows = pd.DataFrame(
        [
            _row(i, p, march, cp, config) if isinstance(p, CurvePoint) else _stored(i, p, march)
            for i, (p, march) in enumerate(points)
        ]
    )
    meta = run_metadata("curve", config.to_dict(), ends=list(state["ends"]), complete=all(state["ends"]))
    atomic_write_table(with_metadata(rows, meta), output)


def _stored(index: int, row: Any, march: int) -> dict[str, Any]:
    """A row of the file being resumed, renumbered."""
    out = dict(row)
    out["point"], out["march"] = index, march
    return out


def _row(index: int, p: CurvePoint, march: int, cp: CurveProblem, config: CurveConfig) -> dict[str, Any]:
    problem = cp.problem.at(cp.second, p.lam2)
    params = problem.params_at(p.lam1)
    section = problem.section(p.x)
    records = p.info.records
    mu = p.multipliers
    return {
        "point": index,
        "march": march,
        config.first: p.lam1,
        config.second: p.lam2,
        "omega_hat": params.omega_hat,
        "y_sec": section[0],
        "ydot_sec": section[1],
        "theta_sec": section[2],
        "thetadot_sec": section[3],
        "theta_absmax": float(np.nanmax(records[:, _column("theta_absmax")])),
        "y_absmax": float(np.nanmax(records[:, _column("y_absmax")])),
        "critical_re": p.critical.real,
        "critical_im": p.critical.imag,
        "max_multiplier": float(np.abs(mu).max()),
        "normal_form": p.normal_form,
        "kappa": p.critical.real / abs(p.critical),
        "event": p.event,
        "multipliers_re": mu.real.tolist(),
        "multipliers_im": mu.imag.tolist(),
        "u": p.u.tolist(),
        "tangent": p.tangent.tolist(),
        "vector": np.real(p.vector).tolist(),
        "step": p.step,
    }


def _column(name: str) -> int:
    from ...kernels import RECORD_COLUMNS

    return RECORD_COLUMNS.index(name)


def _resumable(output: Path, config: CurveConfig) -> dict[str, Any] | None:
    """The finished part of an earlier run of the same configuration at ``output`` (None: start afresh)."""
    if not Path(output).exists():
        return None
    rows, meta = read_results(output)
    if meta.get("kind") != "curve":
        raise ConfigError(f"--resume: {str(output)!r} is not a curve result")
    if meta.get("config_hash") != run_metadata("curve", config.to_dict())["config_hash"]:
        raise ConfigError(f"--resume: {str(output)!r} holds another configuration; give another -o or drop --resume")
    if meta.get("complete"):
        return {"complete": True, "rows": rows}
    return {
        "complete": False,
        "start": rows[rows["march"] == 0].iloc[0],
        "back": [r for _, r in rows[rows["march"] == -1].iloc[::-1].iterrows()],
        "ahead": [r for _, r in rows[rows["march"] == 1].iterrows()],
        "ends": list(meta["ends"]),
    }


def curve_events(rows: pd.DataFrame) -> pd.DataFrame:
    """The rows with an event (codimension-two points and turns)."""
    return rows[rows["event"] != ""]
