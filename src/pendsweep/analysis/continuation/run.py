"""``pendsweep continue``: configuration, start orbits, the run and its JSON document.

The JSON document (issue 15)::

    {"parameter": "alpha", "unit": "N",
     "bifurcations": [{"type": "period-doubling"|"fold"|"neimark-sacker"|"branch-point", "value": v, "branch": i}],
     "branches": [{"period": k, "points": [{"value": v, "section": [y, ydot, theta, thetadot],
                                            "multipliers": [[re, im], ...], "max_multiplier": m,
                                            "stable": bool}]}],
     "branch_ends": [{"branch": i, "origin": ..., "ends": [first end, last end]}],
     "start_shift": d,
     "kind": "continuation", "config": {...}, "config_hash": ..., "package_version": ..., "created": ...}

``section`` is the state at forcing phase 0 [m, m/s, rad, rad/s];
``multipliers`` are the Floquet multipliers of ``P^k`` (complex, as
``[re, im]``); a point is stable when all have modulus below 1. Points are
in arclength order; located bifurcation points are included in their
branch. ``branch-point`` (a multiplier +1 without a fold, such as the
symmetry-breaking pitchfork of the swing near 54 N) extends the issue's three
types. ``start_shift`` is how far Newton moved a given start section
(scaled max-norm: state in units of ``l``, ``l w_e``, 1 rad, ``w_e``; 0
for the semi-trivial start). Points of branch 0 run from the far end
behind the start, through the start, towards ``--to`` (downward when
``--to`` < ``--from``). ``config`` holds everything needed to recompute the document.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ...engine.results import check_writable, read_results, run_metadata
from ...errors import ConfigError
from ...model.params import PARAM_SPECS, ModelParams, check_value
from .core import Continuation
from .problem import Result, Settings
from .shooting import PendulumShooting, semi_trivial_section

#: Model parameters that can be continued (derived M1/C1 are continued as M/C).
MODEL_CONTINUABLE = tuple(name for name in PARAM_SPECS if name not in ("M1", "C1", "M2", "C2"))
#: Every continuable parameter: the model's, and the substructured loop's transfer system
#: (:data:`pendsweep.analysis.continuation.loop.LOOP_PARAMETERS`, with ``--backend substructured`` only).
CONTINUABLE = MODEL_CONTINUABLE + ("transport_delay", "servo_bandwidth", "servo_damping", "tau_hat")
#: Backends whose periodic orbits can be continued.
CONTINUATION_BACKENDS = ("emulated", "substructured")


def parameter_unit(parameter: str) -> str:
    """The unit of a continuable parameter (model or loop)."""
    from .loop import LOOP_PARAMETERS

    return LOOP_PARAMETERS[parameter] if parameter in LOOP_PARAMETERS else PARAM_SPECS[parameter].unit


#: RK4 systems a shooting evaluation integrates: the orbit and its four variational directions.
VARIATIONAL_SYSTEMS = 5
#: Corrector evaluations per point counted for the hybrid loop's work estimate (Newton converges in 2-4).
TYPICAL_CORRECTOR_ITERATIONS = 3


@dataclass(frozen=True)
class ContinuationConfig:
    """A continuation run; stored in full with its result.

    Attributes
    ----------
    parameter : str
        Continued model parameter (:data:`CONTINUABLE`).
    start, stop : float
        The parameter interval [parameter unit]; the run starts at ``start``
        unless ``start_value`` is given.
    model : dict
        Overrides of :class:`~pendsweep.model.params.ModelParams` (SI).
    start_section : tuple of 4 floats or None
        A point of a known orbit at forcing phase 0 ``(y, ydot, theta,
        thetadot)``; ``None`` starts from the semi-trivial solution.
    start_value : float or None
        Parameter value of ``start_section`` (default ``start``).
    period : int
        Period of the start orbit in forcing periods.
    eps : float
        ``sgn(w) ~ tanh(w / eps)`` in the pendulum damping [rad/s]; 0 holds
        the sign per step (non-smooth with b1 > 0, see docs/continuation.md).
    dt : float
        Requested RK4 step [s]; a whole number of steps per forcing period.
    ds, ds_max : float
        First and largest arclength step (scaled units).
    max_points : int
        Points per direction and branch.
    max_period : int
        Largest period reached by branch switching at period doublings.
    newton_tol : float
        Newton tolerance on the scaled max-norm of the update
        (state in units of ``l``, ``l w_e``, 1 rad, ``w_e``).
    backend : {"emulated", "substructured"}
        Whose orbits: Eq. (11) itself, or the simulated hybrid test's tick
        map (:mod:`pendsweep.analysis.continuation.loop`, noise and quantisation off).
    backend_options : dict
        The substructured backend's options (``-B``), as for sweeps; ``dt``
        is the controller step.
    """

    parameter: str
    start: float
    stop: float
    model: dict[str, float] = field(default_factory=dict)
    start_section: tuple[float, float, float, float] | None = None
    start_value: float | None = None
    period: int = 1
    eps: float = 1e-3
    dt: float = 1e-3
    ds: float = 0.02
    ds_max: float = 0.05
    max_points: int = 400
    max_period: int = 4
    newton_tol: float = 1e-10
    backend: str = "emulated"
    backend_options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.backend not in CONTINUATION_BACKENDS:
            raise ConfigError(
                f"--backend {self.backend!r} cannot be continued; choose from {', '.join(CONTINUATION_BACKENDS)}"
            )
        if self.parameter not in CONTINUABLE:
            raise ConfigError(f"cannot continue in {self.parameter!r}; choose from {', '.join(CONTINUABLE)}")
        if self.backend == "emulated":
            if self.parameter not in MODEL_CONTINUABLE:
                raise ConfigError(
                    f"{self.parameter} is an option of the substructured loop: add --backend substructured"
                )
            if self.backend_options:
                raise ConfigError(
                    f"-B {next(iter(self.backend_options))}: the emulated continuation takes no backend options "
                    "(its model is set with --set; --backend substructured for the loop's)"
                )
            for v in (self.start, self.stop):
                check_value(self.parameter, v)
        else:
            if "dt" in self.backend_options:
                raise ConfigError("-B dt: give the controller step as --dt")
            loop_options = dict(self.backend_options)
            if self.parameter in loop_options:
                raise ConfigError(f"-B {self.parameter}: {self.parameter} is the continued parameter (--from/--to)")
            self.loop_backend()  # refuses unknown options, a remote rig and bad values (exit 2)
            if self.parameter in MODEL_CONTINUABLE:
                for v in (self.start, self.stop):
                    check_value(self.parameter, v)
            elif not all(math.isfinite(v) and v >= 0 for v in (self.start, self.stop)):
                raise ConfigError(
                    f"--from/--to of {self.parameter} must be finite numbers >= 0 [{parameter_unit(self.parameter)}]"
                )
        if self.start == self.stop:
            raise ConfigError(f"--from and --to are both {self.start:g}: give an interval")
        ModelParams.from_mapping(self.model)
        if self.start_value is not None:
            lo, hi = sorted((self.start, self.stop))
            if not lo <= self.start_value <= hi:
                raise ConfigError(
                    f"start orbit at {self.parameter} = {self.start_value:g} lies outside [{lo:g}, {hi:g}]"
                )
        if self.start_section is not None:
            object.__setattr__(self, "start_section", tuple(float(v) for v in self.start_section))
            if len(self.start_section) != 4 or not all(math.isfinite(v) for v in self.start_section):
                raise ConfigError(
                    f"start section {self.start_section!r} must be 4 finite numbers (y, ydot, theta, thetadot)"
                )
        checks = (
            ("period", self.period >= 1 and int(self.period) == self.period, "an integer >= 1"),
            ("eps", math.isfinite(self.eps) and self.eps >= 0, "a finite number >= 0 [rad/s]"),
            ("dt", math.isfinite(self.dt) and self.dt > 0, "a finite number > 0 [s]"),
            ("ds", math.isfinite(self.ds) and 0 < self.ds <= 1, "in (0, 1]"),
            ("ds_max", math.isfinite(self.ds_max) and self.ds <= self.ds_max <= 1, "in [ds, 1]"),
            ("max_points", self.max_points >= 1, "an integer >= 1"),
            ("max_period", self.max_period >= 1, "an integer >= 1"),
            ("newton_tol", 1e-14 <= self.newton_tol <= 1e-4, "in [1e-14, 1e-4]"),
        )
        for name, ok, accepted in checks:
            if not ok:
                raise ConfigError(f"{name} = {getattr(self, name)!r} must be {accepted}")
        if 1.0 / self.params().fe < self.dt:
            raise ConfigError(f"dt = {self.dt:g} s is longer than the forcing period {1 / self.params().fe:g} s")

    @property
    def lam0(self) -> float:
        return self.start if self.start_value is None else self.start_value

    def params(self) -> ModelParams:
        """The model at the start value."""
        base = ModelParams.from_mapping(self.model)
        return base.replace(**{self.parameter: self.lam0}) if self.parameter in MODEL_CONTINUABLE else base

    def loop_backend(self):
        """The smoothed substructured backend at the start value (:func:`~pendsweep.analysis.continuation.loop.smoothed_backend`)."""
        from ...backends import make_backend
        from .loop import LOOP_PARAMETERS, smoothed_backend

        options = dict(self.backend_options) | {"dt": self.dt}
        if self.parameter in LOOP_PARAMETERS:
            options[self.parameter] = self.lam0
        return smoothed_backend(make_backend("substructured", **options))

    def problem(self, period: int | None = None):
        """The map problem: :class:`PendulumShooting` or, for the loop, :class:`~pendsweep.analysis.continuation.loop.LoopShooting`."""
        period = self.period if period is None else period
        lam_scale = abs(self.stop - self.start)
        if self.backend == "emulated":
            return PendulumShooting(self.params(), self.parameter, period, self.dt, self.eps, lam_scale=lam_scale)
        from .loop import LoopShooting

        backend = self.loop_backend()
        n_cmd = None
        if self.parameter == "transport_delay":  # the delay line long enough for the whole interval
            n_cmd = dataclasses.replace(backend, transport_delay=max(self.start, self.stop)).n_cmd
        return LoopShooting(backend, self.params(), self.parameter, period, self.eps, lam_scale, n_cmd=n_cmd)

    def start_state(self, section) -> np.ndarray:
        """The continued state of a start section ``(y, ydot, theta, thetadot)`` (the loop's live slots for the loop)."""
        section = np.asarray(section, dtype=float)
        return section if self.backend == "emulated" else self.problem().from_section(section)

    def settings(self) -> Settings:
        return Settings(
            ds=self.ds,
            ds_max=self.ds_max,
            max_points=self.max_points,
            max_period=self.max_period,
            newton_tol=self.newton_tol,
        )

    def work(self):
        """Upper bound on the integration steps (:class:`pendsweep.engine.scan.Work`) before the run starts.

        Every point of both directions of every branch (period ``period``,
        doubled up to ``max_period``) takes at most ``max_iterations`` corrector
        evaluations, each a shooting over the branch's period with the
        variational equations: five RK4 systems of Eq. (11)'s size. The loop's
        monodromy is ``2 m + 1`` loop runs (``m`` live slots), each tick a
        numerical-model step and the rig's substeps.
        """
        from ...engine.scan import Work

        periods, k = 0, self.period
        while k <= max(self.max_period, self.period):
            periods += k
            k *= 2
        evaluations = 2 * self.max_points * self.settings().max_iterations
        problem = self.problem()
        if self.backend == "emulated":
            return Work(evaluations, periods * VARIATIONAL_SYSTEMS, float(problem.steps))
        # The loop's corrector evaluations: a typical 3 per point rather than the bound of max_iterations,
        # because each is 2m + 1 whole-loop runs (the bound refused runs of 10 s by default).
        evaluations = 2 * self.max_points * TYPICAL_CORRECTOR_ITERATIONS
        runs = 2 * problem.live.size + 1
        return Work(evaluations, periods * runs, float(problem.steps * (1 + problem.backend.physics_substeps)))

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["model"] = ModelParams.from_mapping(self.model).to_dict()
        d["start_section"] = None if self.start_section is None else list(self.start_section)
        problem = self.problem()
        d["steps_per_period"] = problem.steps
        if self.backend != "emulated":
            from .loop import smoothing_record

            d["backend_options"] = dataclasses.asdict(problem.backend)
            d["smoothing"] = smoothing_record(self._unsmoothed_backend(), self.eps)
            d["delay_line"] = problem.n_cmd
        return d

    def _unsmoothed_backend(self):
        from ...backends import make_backend

        return make_backend("substructured", **(dict(self.backend_options) | {"dt": self.dt}))


def run_continuation(config: ContinuationConfig, progress: bool = False) -> dict[str, Any]:
    """Run the continuation of ``config`` and return its JSON document (module docstring).

    Raises :class:`~pendsweep.analysis.continuation.ContinuationError` when Newton
    does not converge at the start (a runtime failure).
    """
    from ...engine.scan import progress_bar

    problem = config.problem()
    section = config.start_section if config.start_section is not None else semi_trivial_section(problem.params)
    x0 = config.start_state(section)
    bar = progress_bar(progress, unit="pt", desc=f"continue {config.parameter}")
    try:
        result = Continuation(problem, (config.start, config.stop), config.settings(), progress=bar.update).run(
            x0, config.lam0
        )
    finally:
        bar.close()
    return document(result, config)


def document(result: Result, config: ContinuationConfig) -> dict[str, Any]:
    """The JSON document of a continuation result.

    Every point (and bifurcation) carries its ``section`` ``(y, ydot, theta,
    thetadot)``; the loop's also its whole continued ``state`` (the live
    slots, :mod:`pendsweep.analysis.continuation.loop`), from which it is integrated again.
    """
    problem = config.problem()
    loop = config.backend != "emulated"

    def orbit(x) -> dict[str, Any]:
        out = {"section": [float(v) for v in (problem.section(x) if loop else x)]}
        if loop:
            out["state"] = [float(v) for v in x]
        return out

    def point(pt) -> dict[str, Any]:
        return {
            "value": float(pt.lam),
            **orbit(pt.x),
            "multipliers": [[float(m.real), float(m.imag)] for m in pt.multipliers],
            "max_multiplier": pt.max_multiplier,
            "stable": bool(pt.stable),
        }

    periods = [b.period for b in result.branches]
    doc = {
        "parameter": config.parameter,
        "unit": parameter_unit(config.parameter),
        "bifurcations": [
            {
                "type": b.kind,
                "value": float(b.lam),
                "branch": b.branch,
                "period": periods[b.branch],
                **orbit(b.x),
                "multipliers": [[float(m.real), float(m.imag)] for m in b.multipliers],
            }
            for b in result.bifurcations
        ],
        "branches": [{"period": b.period, "points": [point(p) for p in b.points]} for b in result.branches],
        "branch_ends": [{"branch": i, "origin": b.origin, "ends": list(b.ends)} for i, b in enumerate(result.branches)],
    }
    doc["start_shift"] = start_shift(result, config)
    doc.update(run_metadata("continuation", config.to_dict()))
    return doc


def stored_problem(doc: dict[str, Any], period: int, n_cmd: int | None = None):
    """The map problem of a continuation document's configuration, over ``period`` forcing periods.

    ``n_cmd`` lengthens the loop's delay line (a curve continued into longer delays).
    """
    cfg = doc["config"]
    params = ModelParams.from_mapping(cfg["model"])
    lam_scale = abs(cfg["stop"] - cfg["start"])
    if cfg.get("backend", "emulated") == "emulated":
        return PendulumShooting(
            params, cfg["parameter"], period, cfg["dt"], cfg["eps"], lam_scale, steps=cfg["steps_per_period"]
        )
    from ...backends import make_backend
    from .loop import LoopShooting

    backend = make_backend("substructured", **cfg["backend_options"])
    return LoopShooting(
        backend, params, cfg["parameter"], period, cfg["eps"], lam_scale, cfg["steps_per_period"],
        max(cfg["delay_line"], n_cmd or 0),
    )  # fmt: skip


def write_json(doc: dict[str, Any], path: Path) -> None:
    """Write ``doc`` to ``path`` atomically (a reader sees the old file or the whole new one)."""
    path = Path(path)
    check_writable(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(doc, fh, indent=1)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def read_json(path: Path) -> dict[str, Any]:
    """A continuation document written by :func:`write_json` (ConfigError otherwise)."""
    try:
        doc = json.loads(Path(path).read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"no continuation file at {str(path)!r}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{str(path)!r} is not a readable UTF-8 JSON file ({exc.__class__.__name__})") from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{str(path)!r} is not valid JSON: {exc}") from None
    if not isinstance(doc, dict) or doc.get("kind") != "continuation":
        raise ConfigError(f'{str(path)!r} is not a continuation result (no "kind": "continuation")')
    return doc


#: What a continuation document's ``config`` must hold to rebuild its map problem.
STORED_CONFIG_KEYS = ("parameter", "start", "stop", "model", "dt", "eps", "steps_per_period")


def stored_config(doc: dict[str, Any], path: Path) -> dict[str, Any]:
    """The ``config`` of continuation document ``doc`` (read from ``path``), checked enough to rebuild its problem."""
    cfg = doc.get("config")
    missing = [k for k in STORED_CONFIG_KEYS if not isinstance(cfg, dict) or k not in cfg]
    if missing:
        raise ConfigError(f"{str(path)!r} has no {missing[0]!r} in its config: not a result of `pendsweep continue`")
    if cfg.get("backend", "emulated") != "emulated" and not {"backend_options", "delay_line"} <= set(cfg):
        raise ConfigError(f"{str(path)!r} continues the hybrid loop but stores no backend options")
    try:
        ModelParams.from_mapping(cfg["model"])
    except (TypeError, ValueError, AttributeError) as exc:
        raise ConfigError(f"{str(path)!r}: its model is not valid ({exc})") from None
    return cfg


#: Repeat tolerance of the normalised recorded sections (the classifier's normalisation,
#: :func:`pendsweep.analysis.sections.section_scales`) for a sweep point to count as a start orbit: ten times
#: the classifier's ``PERIODIC_TOL`` - only a Newton start, which need not be exact.
START_REPEAT_TOL = 1e-2

#: A start orbit that Newton moves further than this (scaled max-norm, state in units of ``l``,
#: ``l w_e``, 1 rad, ``w_e``; theta wrapped) is reported: Newton may have found another orbit.
START_SHIFT_WARN = 0.1


def section_period(sections: np.ndarray, y_absmax: float, params: ModelParams) -> int | None:
    """Smallest ``n`` with the recorded sections repeating after ``n`` periods, or ``None``.

    ``sections`` is ``(periods, 4)`` [m, m/s, rad, rad/s]; ``y_absmax`` the
    record's largest |y| [m]. The sections are normalised as the classifier
    normalises them (``y/Y, ydot/(w_e Y), theta, thetadot/w_p``, theta
    wrapped; :func:`pendsweep.analysis.sections.section_scales`) and compared with
    :func:`pendsweep.analysis.sections.section_period` to :data:`START_REPEAT_TOL`,
    so every point the sweep labels ``periodic-n`` qualifies (with a period
    of at most ``n``). Rotating orbits qualify (the section is wrapped).
    """
    from ..sections import section_period as classify_period

    Y = y_absmax if math.isfinite(y_absmax) and y_absmax > 0 else 1.0
    scales = np.array([Y, params.omega_e * Y, 1.0, params.omega_p])
    n = classify_period(sections, scales, START_REPEAT_TOL)
    return n or None


def _start_from_sweep(path: Path, parameter: str, value: float) -> tuple[tuple[float, ...], float, int]:
    """Section, value and period of the first branch's sweep point nearest ``value`` (:func:`start_from_file`)."""
    df, meta = read_results(path)
    config = meta.get("config", {})
    swept = config.get("parameter")
    if swept is None:
        raise ConfigError(f"{str(path)!r} is a {meta.get('kind', 'non-sweep')!r} file, not a sweep to start from")
    if swept != parameter:
        raise ConfigError(f"{str(path)!r} sweeps {swept!r}, not {parameter!r}")
    first = df[(df["direction"] == df["direction"].iloc[0]) & (df["start"] == 0) & (df["status"] == "ok")]
    if first.empty:
        raise ConfigError(f"{str(path)!r} holds no finished point to start from")
    values = np.sort(first[parameter].unique())
    nearest = float(values[np.argmin(np.abs(values - value))])
    rows = first[first[parameter] == nearest].sort_values("period")
    sections = rows[["y_sec", "ydot_sec", "theta_sec", "thetadot_sec"]].to_numpy(dtype=float)
    params = ModelParams.from_mapping(config.get("model", {})).replace(**{parameter: nearest})
    period = section_period(sections, float(rows["y_absmax"].max()), params)
    motion = str(rows["motion"].iloc[-1]) if "motion" in rows else ""
    if motion.startswith("periodic-"):  # the sweep's own verdict, reached with a tighter tolerance
        period = int(motion.split("-")[1])
    if period is None:
        raise ConfigError(
            f"{str(path)!r} at {parameter} = {nearest:g} is {motion or 'unclassified'!r}, not periodic: its "
            f"normalised sections do not repeat (to {START_REPEAT_TOL:g}) with a period of at most "
            f"{(len(sections) - 1) // 2}; choose another --start-value"
        )
    return tuple(sections[-1]), nearest, period


def _number(path: Path, key: str, raw: Any, accepted: str, integer: bool = False) -> float:
    """``raw`` as a finite float (an integer when ``integer``), else a ConfigError naming ``key``."""
    ok = isinstance(raw, (int, float)) and not isinstance(raw, bool) and math.isfinite(raw)
    if ok and integer:
        ok = float(raw).is_integer() and raw >= 1
    if not ok:
        raise ConfigError(f"start file {str(path)!r}: {key} = {json.dumps(raw)} must be {accepted}")
    return float(raw)


def start_from_file(path: Path, parameter: str, value: float) -> tuple[tuple[float, ...], float, int]:
    """A start orbit ``(section, parameter value, period)`` from a file.

    * a sweep result (``.parquet``): the point of the first branch whose value
      is nearest ``value``, its last recorded section, and its period (the
      sweep's ``periodic-n`` label, otherwise :func:`section_period`;
      rotating orbits included);
    * a JSON object ``{"value": v, "section": [4 numbers], "period": k}``
      (``period`` an integer >= 1, default 1), for example one point of a
      continuation document with its branch's period added.

    Raises ConfigError (exit 2) naming the offending value otherwise.
    """
    path = Path(path)
    if path.suffix == ".parquet":
        return _start_from_sweep(path, parameter, value)
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"no start file at {str(path)!r}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(
            f"start file {str(path)!r} is not a readable UTF-8 JSON file ({exc.__class__.__name__}); "
            'give a sweep result (.parquet) or JSON {"value", "section", "period"}'
        ) from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"start file {str(path)!r} is not valid JSON: {exc}") from None
    if not isinstance(data, dict) or "section" not in data or "value" not in data:
        raise ConfigError(f'start file {str(path)!r} must hold {{"value": v, "section": [4 numbers], "period": k}}')
    section = data["section"]
    if not isinstance(section, list) or len(section) != 4:
        raise ConfigError(
            f"start file {str(path)!r}: section = {json.dumps(section)} must be a list of 4 numbers "
            "[y m, ydot m/s, theta rad, thetadot rad/s]"
        )
    numbers = tuple(_number(path, f"section[{i}]", v, "a finite number") for i, v in enumerate(section))
    start_value = _number(
        path, "value", data["value"], f"a finite number ({parameter} [{PARAM_SPECS[parameter].unit}])"
    )
    period = int(_number(path, "period", data.get("period", 1), "an integer >= 1 [forcing periods]", integer=True))
    return numbers, start_value, period


def start_shift(result: Result, config: ContinuationConfig) -> float:
    """Scaled max-norm (theta wrapped) of how far Newton moved the given start section (0 without one)."""
    if config.start_section is None or result.start is None:
        return 0.0
    params = config.params()
    x = np.asarray(result.start.x)
    section = config.problem().section(x) if config.backend != "emulated" else x
    d = section - np.asarray(config.start_section)
    d[2] = (d[2] + np.pi) % (2 * np.pi) - np.pi
    w = params.omega_e
    return float(np.abs(d / np.array([params.l, params.l * w, 1.0, w])).max())
