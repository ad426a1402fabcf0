"""Basins of attraction: many starts integrated until they settle, then grouped into attractors.

The engine is generic over a *stroboscopic map*: any object with

``advance(states, periods, ids) -> (records, states, status)``
    Integrate runs ``ids`` (int64[k], stable run identifiers, e.g. for
    per-run noise seeds) from ``states`` (float64[k, d]) for ``periods``
    forcing periods starting at forcing phase 0; return per-period records
    float64[k, periods, 8] (columns :data:`pendsweep.kernels.RECORD_COLUMNS`),
    the final states float64[k, d] and int64[k] kernel status codes.
``scales_for(ids, records) -> float64[k, 4]``
    Section divisors of runs ``ids`` from their records
    (:func:`pendsweep.classify.section_scales`).

A one-degree-of-freedom system (the tests' Duffing oscillator) puts its
coordinate and velocity in the ``theta`` columns and leaves the ``y``
columns zero.

:func:`settle_runs` integrates all runs in *rounds* of ``round_periods``
forcing periods (no transient; each round continues from the previous
round's final states) and drops a run as soon as
:func:`pendsweep.attractors.settling` finds it settled, or after
``max_periods``. Early stop is what makes a 200 x 200 basin map with a
1000-period cap affordable: the cost is the integral of the survival curve,
not ``starts x max_periods``.

:func:`summarize` turns the per-run outcome into the attractor table,
fractions per attractor and per motion class with binomial standard errors,
the settling-time distribution and, when the survival curve has an
exponential tail, the escape rate of the chaotic transient.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from .attractors import (
    MATCH_TOL,
    ROTATION_WINDOW,
    SETTLE_TOL,
    SETTLE_WINDOW,
    Attractor,
    cycle_distance,
    identify_attractors,
    repeat_mask,
    section_scales_many,
    settling,
)
from .classify import MAX_PERIOD
from .errors import ConfigError
from .kernels import STATUS_DIVERGED, STATUS_OK, STATUS_UNSTABLE
from .kernels._layout import REC_THETA_ABSMAX, REC_THETADOT_SEC, REC_Y_SEC
from .params import ModelParams
from .status import Status

if TYPE_CHECKING:  # pandas (0.3 s) is imported by the functions that build frames, not by importing this module
    import pandas as pd

#: Forcing periods integrated between settling checks.
ROUND_PERIODS = 25
#: Starts per task (unit of persistence and of parallel work).
CHUNK_STARTS = 4096
#: Settling tolerance on backends with sensor noise and quantisation [normalised, ~rad]: about 8 encoder pulses.
NOISY_SETTLE_TOL = 0.01
#: Escape rate: fewest settling events in the fitted tail.
ESCAPE_MIN_EVENTS = 20

_SEC = slice(REC_Y_SEC, REC_THETADOT_SEC + 1)
_STATUS_CODE = {Status.OK: STATUS_OK, Status.DIVERGED: STATUS_DIVERGED, Status.UNSTABLE: STATUS_UNSTABLE}


class StroboscopicMap(Protocol):
    """What :func:`settle_runs` integrates (see the module docstring)."""

    def advance(self, states: np.ndarray, periods: int, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(records (k, periods, 8), final states (k, d), status codes (k,))`` from phase 0."""
        ...

    def scales_for(self, ids: np.ndarray, records: np.ndarray) -> np.ndarray:
        """Section divisors ``(k, 4)`` of runs ``ids`` from their records."""
        ...


@dataclass(frozen=True)
class EmulatedMap:
    """The emulated system as a stroboscopic map, on the batched kernel.

    Attributes
    ----------
    params : tuple of ModelParams
        One parameter set, or one per run (indexed by the run ids).
    dt : float
        Requested step [s] (see :class:`pendsweep.backends.EmulatedBackend`).
    signum : {"step", "stage"}
    threads : int, optional
        numba threads (default: all).
    device, precision : str
        ``"cpu"`` or ``"cuda"`` and the GPU's ``"float64"``/``"float32"``
        (see :func:`pendsweep.backends._batch.run_batch`).
    """

    params: tuple[ModelParams, ...]
    dt: float = 1e-3
    signum: str = "step"
    threads: int | None = None
    device: str = "cpu"
    precision: str = "float64"

    def _params_of(self, ids: np.ndarray) -> list[ModelParams]:
        return [self.params[0]] * len(ids) if len(self.params) == 1 else [self.params[i] for i in ids]

    def advance(self, states, periods, ids):
        from .backends._batch import run_batch

        run = run_batch(
            self._params_of(ids), states, 0, periods, dt=self.dt, signum=self.signum, threads=self.threads,
            device=self.device, precision=self.precision,
        )  # fmt: skip
        return run.records, run.states, run.status

    def scales_for(self, ids: np.ndarray, records: np.ndarray) -> np.ndarray:
        ps = self._params_of(ids)
        we = np.array([p.omega_e for p in ps]) if len(self.params) > 1 else self.params[0].omega_e
        wp = np.array([p.omega_p for p in ps]) if len(self.params) > 1 else self.params[0].omega_p
        return section_scales_many(records, we, wp)


@dataclass(frozen=True)
class BackendMap:
    """Any registered backend as a stroboscopic map, one run at a time (threads across runs).

    Each run gets its own noise seed, ``SeedSequence([*entropy, run id])``,
    when the backend has a ``seed`` option, so runs see independent noise.
    """

    backend: Any
    params: ModelParams
    entropy: tuple[int, ...] = (0,)
    workers: int = 2

    def _backend_for(self, run_id: int):
        if not hasattr(self.backend, "seed"):
            return self.backend
        seed = int(np.random.SeedSequence([*self.entropy, int(run_id)]).generate_state(1)[0])
        return replace(self.backend, seed=seed)

    def advance(self, states, periods, ids):
        def one(i):
            run = self._backend_for(ids[i]).run_point(self.params, states[i], 0, periods)
            return run.records, run.state, _STATUS_CODE[run.status]

        with ThreadPoolExecutor(max(1, self.workers)) as pool:
            out = list(pool.map(one, range(len(ids))))
        if not out:
            return np.empty((0, periods, 8)), np.asarray(states), np.zeros(0, dtype=np.int64)
        return (
            np.stack([o[0] for o in out]),
            np.stack([o[1] for o in out]),
            np.array([o[2] for o in out], dtype=np.int64),
        )

    def scales_for(self, ids: np.ndarray, records: np.ndarray) -> np.ndarray:
        return section_scales_many(records, self.params.omega_e, self.params.omega_p)


@dataclass
class SettledRuns:
    """Per-run outcome of :func:`settle_runs` (arrays over ``k`` runs).

    Attributes
    ----------
    status : int64[k]
        Kernel status code (0 ok, 1 diverged, 2 unstable).
    settled : bool[k]
    period, turns : int64[k]
        Cycle length [forcing periods] and net rotations per cycle.
    at_rest : bool[k]
    settle_periods : int64[k]
        Forcing periods from the start to the first section of the settled
        stretch (repeating to ``SETTLE_TOL``); -1 when not settled.
    escape_periods : int64[k]
        Forcing periods from the start until the section stays within
        :data:`~pendsweep.attractors.MATCH_TOL` of repeating with the settled
        cycle: the end of the irregular (e.g. chaotic) transient, before the
        slow final convergence; -1 when not settled.
    periods_done : int64[k]
        Forcing periods integrated.
    cycle : float64[k, MAX_PERIOD, 4]
        The last ``period`` section points ``(y, ydot, theta, thetadot)``
        (NaN-padded; NaN when not settled).
    scales : float64[k, 4]
        Section divisors over the last window.
    theta_absmax : float64[k]
        max |theta| [rad] over the final window (the settled motion's swing).
    states : float64[k, d]
        Final states.
    """

    status: np.ndarray
    settled: np.ndarray
    period: np.ndarray
    turns: np.ndarray
    at_rest: np.ndarray
    settle_periods: np.ndarray
    escape_periods: np.ndarray
    periods_done: np.ndarray
    cycle: np.ndarray
    scales: np.ndarray
    theta_absmax: np.ndarray
    states: np.ndarray

    @property
    def motion(self) -> np.ndarray:
        """Motion class per run (``unsettled`` after the cap, ``n/a`` when it failed)."""
        from .attractors import motion_label

        out = np.full(self.status.shape, "unsettled", dtype=object)
        out[self.status != 0] = "n/a"
        for i in np.flatnonzero(self.settled):
            out[i] = motion_label(bool(self.at_rest[i]), int(self.period[i]), int(self.turns[i]))
        return out


def settle_runs(
    system: StroboscopicMap,
    states: np.ndarray,
    max_periods: int,
    *,
    ids: np.ndarray | None = None,
    round_periods: int = ROUND_PERIODS,
    on_round: Callable[[int], None] | None = None,
    **settle_options: Any,
) -> SettledRuns:
    """Integrate runs in rounds until each has settled or reached ``max_periods``.

    Parameters
    ----------
    system : StroboscopicMap
    states : float64[k, d]
        Initial states at forcing phase 0.
    max_periods : int
        Cap on forcing periods per run; runs not settled by then are
        ``unsettled``.
    ids : int64[k], optional
        Run identifiers passed to ``system.advance`` (default ``0 .. k-1``).
    round_periods : int
        Forcing periods per round.
    on_round : callable, optional
        Called with the number of runs finished in each round (progress).
    **settle_options
        Passed to :func:`pendsweep.attractors.settling` (``tol``, ``window`` ...).

    Returns
    -------
    SettledRuns
    """
    states = np.array(states, dtype=np.float64, copy=True)
    k = states.shape[0]
    ids = np.arange(k, dtype=np.int64) if ids is None else np.asarray(ids, dtype=np.int64)
    window = settle_options.get("window", SETTLE_WINDOW)
    history_rows = max(
        window + settle_options.get("max_period", MAX_PERIOD), settle_options.get("rotation_window", ROTATION_WINDOW)
    )
    out = SettledRuns(
        status=np.zeros(k, dtype=np.int64),
        settled=np.zeros(k, dtype=bool),
        period=np.zeros(k, dtype=np.int64),
        turns=np.zeros(k, dtype=np.int64),
        at_rest=np.zeros(k, dtype=bool),
        settle_periods=np.full(k, -1, dtype=np.int64),
        escape_periods=np.full(k, -1, dtype=np.int64),
        periods_done=np.zeros(k, dtype=np.int64),
        cycle=np.full((k, MAX_PERIOD, 4), np.nan),
        scales=np.ones((k, 4)),
        theta_absmax=np.full(k, np.nan),
        states=states,
    )
    active = np.arange(k)
    history = np.empty((k, 0, 8))
    # near_since[i, n-1]: first period since which run i's section has stayed within MATCH_TOL
    # of repeating after n periods (updated every round, so no long history is kept).
    max_period = settle_options.get("max_period", MAX_PERIOD)
    near_since = np.zeros((k, max_period), dtype=np.int64)
    done = 0
    while active.size and done < max_periods:
        periods = min(round_periods, max_periods - done)
        records, new_states, status = system.advance(states[active], periods, ids[active])
        buffer = np.concatenate([history, records], axis=1)
        first_row = done + periods - buffer.shape[1]  # periods elapsed before the buffer's first row
        done += periods
        states[active] = new_states
        out.periods_done[active] = done
        scales = system.scales_for(ids[active], buffer[:, -window:])
        for n in range(1, max_period + 1):
            recent = buffer[:, -(periods + n) :]  # the pairs whose later section is in this round
            near = repeat_mask(recent, scales, n, MATCH_TOL)
            broken = ~near
            any_break = broken.any(axis=1)
            last_break = near.shape[1] - 1 - np.argmax(broken[:, ::-1], axis=1)
            pair_first = first_row + buffer.shape[1] - recent.shape[1]  # row of column 0's earlier section
            near_since[active[any_break], n - 1] = pair_first + last_break[any_break] + 1
        found = settling(buffer, scales, **settle_options)
        failed = status != 0
        last = done >= max_periods
        finished = found.settled | failed | last
        f = np.flatnonzero(finished)
        idx = active[f]
        out.status[idx] = status[f]
        ok = found.settled[f] & ~failed[f]
        out.settled[idx] = ok
        out.period[idx] = np.where(ok, found.period[f], 0)
        out.turns[idx] = np.where(ok, found.turns[f], 0)
        out.at_rest[idx] = ok & found.at_rest[f]
        out.settle_periods[idx] = np.where(ok, first_row + found.onset[f] + 1, -1)
        near_onset = near_since[idx, np.maximum(found.period[f], 1) - 1] + 1
        near_onset = np.where(found.period[f] > 0, near_onset, out.settle_periods[idx])  # steady rotation: no cycle
        out.escape_periods[idx] = np.where(ok, np.minimum(near_onset, out.settle_periods[idx]), -1)
        out.scales[idx] = scales[f]
        out.theta_absmax[idx] = np.fmax.reduce(buffer[f, -window:, REC_THETA_ABSMAX], axis=1)
        for j, i in zip(f[ok], idx[ok]):
            n = max(int(found.period[j]), 1)
            out.cycle[i, :n] = buffer[j, buffer.shape[1] - n :, _SEC]
        keep = ~finished
        active = active[keep]
        history = buffer[keep, -history_rows:]
        if on_round is not None:
            on_round(int(f.size))
    return out


# -- statistics ------------------------------------------------------------------


def binomial_stderr(fraction: float, n: int) -> float:
    """Standard error sqrt(f (1 - f) / n) of a fraction estimated from n independent samples."""
    return math.sqrt(fraction * (1.0 - fraction) / n) if n > 0 else math.nan


def survival(settle_periods: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Fraction of runs not yet settled after each of ``times`` [periods] (unsettled: -1, never)."""
    t = np.where(settle_periods < 0, np.inf, settle_periods)
    return (t[None, :] > np.asarray(times)[:, None]).mean(axis=1)


def settling_quantile(settle_periods: np.ndarray, q: float) -> float | None:
    """Quantile ``q`` of the settling time over all runs, unsettled runs counted as never settling.

    None when more than ``1 - q`` of the runs never settled (the quantile lies beyond the cap).
    """
    t = np.sort(np.where(settle_periods < 0, np.inf, settle_periods).astype(float))
    if t.size == 0:
        return None
    value = t[min(t.size - 1, int(math.ceil(q * t.size)) - 1)]
    return float(value) if math.isfinite(value) else None


def escape_rate(settle_periods: np.ndarray, max_periods: int) -> dict[str, Any] | None:
    """Escape rate of a chaotic transient from the survival curve's exponential stretch.

    The stretch runs from the median settling time ``t0`` (the fast, direct
    settlers are past) to the 95 % quantile ``t1`` (or the cap), leaving out
    a sparse tail of slow settlers. With a constant hazard kappa the settling
    times there are exponential, and the censored maximum-likelihood
    estimate is kappa = d / exposure (d settling events in the stretch,
    exposure the periods the runs at risk spent unsettled in it), with
    standard error kappa / sqrt(d). The stretch counts as exponential (a
    transient with a rate exists) when it holds at least
    :data:`ESCAPE_MIN_EVENTS` events and the hazards of its first and last thirds agree
    within 30 % of the overall rate plus 3 combined standard errors.

    Returns
    -------
    dict or None
        ``rate`` and ``stderr`` [1/forcing period], ``lifetime`` (1/rate
        [periods]), ``from``/``to`` (the stretch [periods]), ``events`` and
        ``rate_thirds``; None when there is no exponential stretch.
    """
    t = np.where(settle_periods < 0, np.inf, settle_periods).astype(float)
    t0 = settling_quantile(settle_periods, 0.5) or 0.0
    t1 = settling_quantile(settle_periods, 0.95)
    t1 = float(max_periods) if t1 is None else t1
    if not t1 > t0:
        return None

    def hazard(a: float, b: float) -> tuple[float, int]:
        at_risk = t[t > a]
        events = int(np.count_nonzero(at_risk <= b))
        exposure = float(np.sum(np.minimum(at_risk, b) - a))
        return (events / exposure if exposure > 0 else math.nan), events

    rate, events = hazard(t0, t1)
    if events < ESCAPE_MIN_EVENTS or not rate > 0:
        return None
    edges = np.linspace(t0, t1, 4)
    parts = [hazard(a, b) for a, b in zip(edges[:-1], edges[1:])]
    if min(e for _, e in parts) < 5:
        return None
    rates = np.array([r for r, _ in parts])
    errors = rates / np.sqrt([e for _, e in parts])
    # A constant hazard: no trend from the first third to the last beyond 30 % plus the noise.
    if abs(rates[2] - rates[0]) > 0.3 * rate + 3.0 * math.hypot(errors[0], errors[2]):
        return None
    return {
        "rate": rate,
        "stderr": rate / math.sqrt(events),
        "lifetime": 1.0 / rate,
        "from": t0,
        "to": t1,
        "events": events,
        "rate_thirds": rates.tolist(),
    }


def class_fractions(motion: np.ndarray) -> tuple[dict[str, float], dict[str, float]]:
    """Fraction of runs per motion class and its binomial standard error."""
    n = motion.size
    labels, counts = np.unique(motion.astype(str), return_counts=True)
    order = np.argsort(-counts, kind="stable")
    fractions = {str(labels[i]): counts[i] / n for i in order}
    return fractions, {k: binomial_stderr(f, n) for k, f in fractions.items()}


def summarize(
    runs: SettledRuns, max_periods: int, match_tol: float | None = None
) -> tuple[dict[str, Any], np.ndarray, list[Attractor]]:
    """The basin summary of one parameter point.

    Returns
    -------
    summary : dict
        JSON-able: ``fractions`` and ``stderr`` per motion class (all runs,
        ``unsettled`` included), ``unsettled``, ``settling_periods``
        (``median``, ``q90``; None beyond the cap), ``escape_rate`` (rate per
        forcing period, or None) and ``escape``, ``attractors`` (one entry
        per attractor: id, motion, period, rotation_number, fraction,
        stderr, theta_absmax, section cycle, mirror), ``runs``,
        ``max_periods``, ``diverged``.
    labels : int64[k]
        Attractor id per run (-1: unsettled or failed).
    attractors : list of Attractor
    """
    ok = runs.settled & (runs.status == 0)
    kwargs = {} if match_tol is None else {"tol": match_tol}
    sub, attractors = identify_attractors(
        runs.cycle[ok], runs.period[ok], runs.turns[ok], runs.at_rest[ok], runs.scales[ok], **kwargs
    )
    labels = np.full(runs.status.shape, -1, dtype=np.int64)
    labels[ok] = sub
    n = runs.status.size
    motion = runs.motion
    fractions, stderr = class_fractions(motion)
    table = []
    for a_id, a in enumerate(attractors):
        members = labels == a_id
        f = float(members.mean()) if n else math.nan
        mirror = next((j for j, b in enumerate(attractors) if j != a_id and a.mirror_of(b)), None)
        table.append(
            {
                "id": a_id,
                "motion": a.motion,
                "period": a.period,
                "rotation_number": a.rotation_number,
                "fraction": f,
                "stderr": binomial_stderr(f, n),
                "count": int(members.sum()),
                "theta_absmax": float(np.nanmedian(runs.theta_absmax[members])) if members.any() else math.nan,
                "cycle": a.cycle.tolist(),
                "mirror": mirror,
            }
        )
    escape = escape_rate(runs.escape_periods, max_periods)
    summary = {
        "fractions": fractions,
        "stderr": stderr,
        "unsettled": fractions.get("unsettled", 0.0),
        "settling_periods": {
            "median": settling_quantile(runs.settle_periods, 0.5),
            "q90": settling_quantile(runs.settle_periods, 0.9),
        },
        "escape_periods": {
            "median": settling_quantile(runs.escape_periods, 0.5),
            "q90": settling_quantile(runs.escape_periods, 0.9),
        },
        "escape_rate": None if escape is None else escape["rate"],
        "escape": escape,
        "attractors": table,
        "runs": int(n),
        "diverged": int(np.count_nonzero(runs.status != 0)),
        "max_periods": int(max_periods),
    }
    return summary, labels, attractors


# -- configured runs, persisted like sweeps ---------------------------------------

SAMPLINGS = ("random", "grid")


@dataclass(frozen=True)
class BasinConfig:
    """Everything that determines a basin run (stored in every result file).

    Attributes
    ----------
    parameter : str
        Model parameter held at each of ``values`` (one value: a single basin).
    values : tuple of float
        Parameter values, ascending.
    model : dict
        Overrides of the default :class:`~pendsweep.params.ModelParams`.
    sampling : {"random", "grid"}
        ``random``: ``samples`` starts drawn from ``default_rng([seed, point])``
        exactly as multistart sweeps draw theta and thetadot (sample i is
        multistart start i + 1); ``grid``: a cell-centred ``grid`` of
        (theta, thetadot) starts (symmetric ranges give a grid symmetric
        about 0 that avoids theta = +-pi).
    theta_range : (float, float)
        Initial theta interval [rad] (default (-pi, pi]).
    thetadot_range : (float, float) or None
        Initial thetadot interval [rad/s]; None: (-w_p, w_p) at each point.
    max_periods : int
        Cap on forcing periods per start.
    round_periods : int
        Periods between settling checks.
    tol : float, optional
        Settling tolerance [normalised, ~rad]. Default
        :data:`~pendsweep.attractors.SETTLE_TOL` (1e-3) on the emulated
        backend and :data:`NOISY_SETTLE_TOL` on others, whose sections carry
        sensor noise and encoder quantisation (one pulse is 1.3e-3 rad).
    backend, backend_options
        Registered backend and its options; ``emulated`` runs on the batched
        kernel, others one start at a time with per-start noise seeds.
    """

    parameter: str
    values: tuple[float, ...]
    model: dict[str, float] = field(default_factory=dict)
    sampling: str = "random"
    samples: int = 1000
    grid: tuple[int, int] = (100, 100)
    seed: int = 0
    theta_range: tuple[float, float] = (-math.pi, math.pi)
    thetadot_range: tuple[float, float] | None = None
    max_periods: int = 1000
    round_periods: int = ROUND_PERIODS
    tol: float | None = None
    backend: str = "emulated"
    backend_options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (isinstance(self.seed, int) and 0 <= self.seed < 2**63):
            raise ConfigError(f"seed = {self.seed!r} must be an integer in [0, 2**63) (numpy's seed sequences)")
        if self.tol is None:
            object.__setattr__(self, "tol", SETTLE_TOL if self.backend == "emulated" else NOISY_SETTLE_TOL)
        if not (math.isfinite(self.tol) and 0 < self.tol < MATCH_TOL):
            raise ConfigError(f"tol = {self.tol!r} must lie in (0, {MATCH_TOL:g}) (normalised section units, ~rad)")
        from .params import PARAM_SPECS, check_value

        if self.parameter not in PARAM_SPECS:
            raise ConfigError(f"unknown parameter {self.parameter!r}; known: {', '.join(PARAM_SPECS)}")
        if not self.values:
            raise ConfigError("a basin run needs at least one parameter value")
        object.__setattr__(self, "values", tuple(sorted(check_value(self.parameter, float(v)) for v in self.values)))
        if self.sampling not in SAMPLINGS:
            raise ConfigError(f"sampling = {self.sampling!r}; choose one of {', '.join(SAMPLINGS)}")
        object.__setattr__(self, "grid", tuple(int(g) for g in self.grid))
        for name, v, lo in (
            ("samples", self.samples, 1),
            ("grid theta", self.grid[0], 1),
            ("grid thetadot", self.grid[1], 1),
            ("max_periods", self.max_periods, SETTLE_WINDOW),
            ("round_periods", self.round_periods, 1),
        ):
            if int(v) != v or v < lo:
                raise ConfigError(f"{name} = {v!r} must be an integer >= {lo}")
        ranges = [("theta", self.theta_range)] + ([("thetadot", self.thetadot_range)] if self.thetadot_range else [])
        for name, r in ranges:
            if len(r) != 2 or not all(math.isfinite(x) for x in r) or not r[0] < r[1]:
                raise ConfigError(f"{name} range {r!r} must be two finite numbers A < B")
        for v in self.values:
            self.params_at(v)
        self.make_backend().validate(self.params_at(self.values[0]))

    @property
    def starts(self) -> int:
        return self.samples if self.sampling == "random" else self.grid[0] * self.grid[1]

    def params_at(self, value: float) -> ModelParams:
        return ModelParams.from_mapping(self.model).replace(**{self.parameter: value})

    def make_backend(self):
        from .backends import make_backend

        return make_backend(self.backend, **self.backend_options)

    def initial_conditions(self, point: int) -> tuple[np.ndarray, np.ndarray]:
        """``(theta0 [rad], thetadot0 [rad/s])``, each ``(starts,)``, of one point (y = ydot = 0)."""
        wp = self.params_at(self.values[point]).omega_p
        (ta, tb), (da, db) = self.theta_range, self.thetadot_range or (-wp, wp)
        if self.sampling == "random":
            rng = np.random.default_rng([self.seed, point])
            n = self.samples
            return tb - (tb - ta) * rng.random(n), da + (db - da) * rng.random(n)
        nt, nd = self.grid
        theta = ta + (tb - ta) * (np.arange(nt) + 0.5) / nt
        thetadot = da + (db - da) * (np.arange(nd) + 0.5) / nd
        tt, dd = np.meshgrid(theta, thetadot, indexing="ij")
        return tt.ravel(), dd.ravel()

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["values"] = list(self.values)
        d["grid"] = list(self.grid)
        d["theta_range"] = list(self.theta_range)
        d["thetadot_range"] = None if self.thetadot_range is None else list(self.thetadot_range)
        d["model"] = ModelParams.from_mapping(self.model).to_dict()
        d["backend_options"] = self.make_backend().options()
        d["settle"] = {
            "window": SETTLE_WINDOW,
            "max_period": MAX_PERIOD,
            "match_tol": MATCH_TOL,
            "rotation_window": ROTATION_WINDOW,
        }
        return d


ROW_COLUMNS = ["point", "start"]


def system_for(config: BasinConfig, point: int, workers: int) -> StroboscopicMap:
    """The stroboscopic map of one parameter point on the configured backend."""
    backend = config.make_backend()
    params = config.params_at(config.values[point])
    if backend.name == "emulated":
        return EmulatedMap((params,), backend.dt, backend.signum, device=backend.device, precision=backend.precision)
    return BackendMap(backend, params, (config.seed, point), workers)


def runs_frame(config: BasinConfig, point: int, starts: np.ndarray, runs: SettledRuns) -> pd.DataFrame:
    """One row per start: its initial condition and outcome (cycle as a 32-float list, NaN-padded)."""
    theta0, thetadot0 = config.initial_conditions(point)
    import pandas as pd

    df = pd.DataFrame(
        {
            config.parameter: config.values[point],
            "point": np.int64(point),
            "start": starts.astype(np.int64),
            "theta0": theta0[starts],
            "thetadot0": thetadot0[starts],
            "status": [Status.from_code(c).value for c in runs.status],
            "motion": runs.motion.astype(str),
            "period": runs.period,
            "rotation_number": runs.turns / np.maximum(runs.period, 1),
            "turns": runs.turns,
            "settle_periods": runs.settle_periods,
            "escape_periods": runs.escape_periods,
            "periods_done": runs.periods_done,
            "theta_absmax": runs.theta_absmax,
        }
    )
    df["cycle"] = list(runs.cycle.reshape(len(starts), -1))
    df["scales"] = list(runs.scales)
    return df


def runs_from_frame(df: pd.DataFrame) -> SettledRuns:
    """Rebuild :class:`SettledRuns` from stored rows (for summaries of finished or resumed runs)."""
    k = len(df)
    status = np.array([_STATUS_CODE[Status(s)] for s in df["status"]], dtype=np.int64)
    motion = df["motion"].to_numpy().astype(str)
    settled = ~np.isin(motion, ["unsettled", "n/a"])
    return SettledRuns(
        status=status,
        settled=settled,
        period=df["period"].to_numpy(np.int64),
        turns=df["turns"].to_numpy(np.int64),
        at_rest=motion == "semi-trivial",
        settle_periods=df["settle_periods"].to_numpy(np.int64),
        escape_periods=df["escape_periods"].to_numpy(np.int64),
        periods_done=df["periods_done"].to_numpy(np.int64),
        cycle=np.stack(df["cycle"].to_numpy()).reshape(k, MAX_PERIOD, 4) if k else np.empty((0, MAX_PERIOD, 4)),
        scales=np.stack(df["scales"].to_numpy()) if k else np.empty((0, 4)),
        theta_absmax=df["theta_absmax"].to_numpy(float),
        states=np.empty((k, 0)),
    )


def _basin_task(config: BasinConfig, point: int, starts: np.ndarray, workers: int) -> list:
    from .scan import UnitResult

    params = config.params_at(config.values[point])
    theta0, thetadot0 = config.initial_conditions(point)
    backend = config.make_backend()
    states = np.stack([backend.initial_state(params, 0.0, 0.0, theta0[s], thetadot0[s]) for s in starts])
    system = system_for(config, point, workers)
    runs = settle_runs(
        system, states, config.max_periods, ids=starts, round_periods=config.round_periods, tol=config.tol
    )
    return [UnitResult(unit_key(point, int(starts[0])), runs_frame(config, point, starts, runs))]


def unit_key(point: int, first_start: int) -> str:
    """Key of one unit of a basin scan: the chunk of starts of ``point`` beginning at ``first_start``."""
    return f"{int(point)}:{int(first_start)}"


@dataclass
class BasinScan:
    """A basin computation as a :class:`pendsweep.scan.Scan`: one unit per chunk of starts of one point."""

    config: BasinConfig
    chunk_starts: int = CHUNK_STARTS
    desc: str = "basins"
    row_columns: list[str] = field(default_factory=lambda: list(ROW_COLUMNS))

    def metadata(self) -> dict[str, Any]:
        from .results import run_metadata

        return run_metadata("basins", self.config.to_dict(), backend=self.config.backend, seed=self.config.seed)

    def _chunks(self) -> list[tuple[int, np.ndarray]]:
        n = self.config.starts
        return [
            (point, np.arange(first, min(first + self.chunk_starts, n)))
            for point in range(len(self.config.values))
            for first in range(0, n, self.chunk_starts)
        ]

    def n_units(self) -> int:
        return len(self._chunks())

    def work(self):
        """Upper bound: every start integrated to the cap (early stop typically does 10-30 % of it).

        Its results take about :data:`RESULT_ROW_BYTES` per start when gathered.
        """
        from .backends import steps_per_period
        from .scan import RESULT_ROW_BYTES, Work

        dt = self.config.make_backend().options().get("dt", 1e-3)
        steps = np.mean([steps_per_period(self.config.params_at(v).fe, dt) for v in self.config.values])
        starts = len(self.config.values) * self.config.starts
        return Work(starts, self.config.max_periods, float(steps), result_bytes=starts * RESULT_ROW_BYTES)

    def tasks(self, finished, n_jobs: int):
        workers = (os.cpu_count() or 1) if n_jobs < 1 else n_jobs
        todo = [(p, st) for p, st in self._chunks() if unit_key(p, int(st[0])) not in finished.keys]
        # The emulated backend's batched kernel uses every core within a task: tasks run one at a time locally.
        return [functools.partial(_basin_task, self.config, p, st, workers) for p, st in todo], 1

    def order(self, df: pd.DataFrame) -> pd.DataFrame:
        return df.sort_values(self.row_columns, kind="stable").reset_index(drop=True)


def run_basins(
    config: BasinConfig,
    output: Path | None = None,
    *,
    n_jobs: int = -1,
    progress: bool = False,
    overwrite: bool = False,
    executor=None,
    chunk_starts: int = CHUNK_STARTS,
    max_work: float | None = None,
    checkpoint_seconds: float = 1.0,
) -> pd.DataFrame:
    """Run (or resume) a basin computation; return one row per (point, start).

    Starts go in units of ``chunk_starts`` (one parameter point each), run
    by the scan engine (:func:`pendsweep.scan.run_scan`): a finished unit is
    persisted through :class:`~pendsweep.results.ResultStore` at most
    ``checkpoint_seconds`` s after it finishes, so a rerun of the same configuration skips it. On the emulated backend a
    unit runs the batched kernel on all cores (units one after another
    locally, in parallel on Dask); on other backends a unit's starts run on
    ``n_jobs`` threads. ``max_work`` limits the work estimate, an upper
    bound (every start to the cap); None: no limit.
    """
    from .scan import run_scan

    scan = BasinScan(config, chunk_starts)
    return run_scan(
        scan,
        output,
        n_jobs=n_jobs,
        progress=progress,
        overwrite=overwrite,
        executor=executor,
        max_work=max_work,
        checkpoint_seconds=checkpoint_seconds,
    )


# -- summaries of finished runs ----------------------------------------------------

#: Attractors at neighbouring parameter values are one branch when their cycles lie this close [normalised].
CONTINUATION_TOL = 0.5
#: The paper's transient [forcing periods]: the scan reports the fraction still unsettled after it.
PAPER_TRANSIENT = 100


def point_summary(df_point: pd.DataFrame, max_periods: int) -> tuple[dict[str, Any], np.ndarray, list[Attractor]]:
    """:func:`summarize` of one point's stored rows, plus the fraction unsettled after 100 periods.

    That fraction is NaN when the runs stopped earlier (``max_periods`` < 100): a
    run unsettled at its cap may settle before 100.
    """
    runs = runs_from_frame(df_point)
    summary, labels, attractors = summarize(runs, max_periods)
    n = runs.status.size
    s100 = i100 = math.nan
    if max_periods >= PAPER_TRANSIENT:
        s100 = float(survival(runs.settle_periods, np.array([PAPER_TRANSIENT]))[0])
        i100 = float(survival(runs.escape_periods, np.array([PAPER_TRANSIENT]))[0])
    summary["unsettled_after_100"] = s100
    summary["unsettled_after_100_stderr"] = binomial_stderr(s100, n)
    summary["irregular_after_100"] = i100
    summary["irregular_after_100_stderr"] = binomial_stderr(i100, n)
    return summary, labels, attractors


def scan_summary(config: BasinConfig, df: pd.DataFrame) -> tuple[dict[str, Any], pd.DataFrame]:
    """Summaries per point, attractors matched across parameter values, and rows with an ``attractor`` column.

    Attractors at consecutive values are the same branch when they have the
    same cycle length and turns and their cycles lie within
    :data:`CONTINUATION_TOL` of each other (the closest one wins); each
    branch gets a global id. The returned rows carry that id per start
    (-1: unsettled or failed).

    Returns
    -------
    summary : dict
        For one value, the point's summary (see :func:`summarize`) with
        ``parameter`` and ``value`` added. For several: ``parameter``,
        ``values``, ``classes`` and ``classes_stderr`` (fraction per motion
        class per value), ``unsettled_after_100`` (+ ``_stderr``),
        ``attractors`` (global id, motion, period, rotation_number,
        ``fractions`` and ``stderr`` per value, ``theta_absmax`` per value)
        and ``points`` (each point's own summary).
    rows : DataFrame
    """
    df = df.sort_values(ROW_COLUMNS, kind="stable").reset_index(drop=True)
    points, globals_, previous = [], [], []  # previous: [(global id, Attractor)] at the last value
    global_labels = np.full(len(df), -1, dtype=np.int64)
    for point, value in enumerate(config.values):
        rows = np.flatnonzero(df["point"].to_numpy() == point)
        summary, labels, attractors = point_summary(df.iloc[rows], config.max_periods)
        mapping, current, taken = {}, [], set()
        for a_id, a in enumerate(attractors):
            best, best_d = None, CONTINUATION_TOL
            for g, b in previous:
                if g in taken or b.period != a.period or b.turns != a.turns or b.motion != a.motion:
                    continue
                d = 0.0 if a.period == 0 else float(cycle_distance(a.cycle[None], b.cycle, a.scales)[0])
                if d < best_d:
                    best, best_d = g, d
            if best is None:
                best = len(globals_)
                globals_.append(
                    {"id": best, "motion": a.motion, "period": a.period, "rotation_number": a.rotation_number}
                )
            taken.add(best)
            mapping[a_id] = best
            current.append((best, a))
        previous = current
        for entry in summary["attractors"]:
            entry["global_id"] = mapping[entry["id"]]
        ok = labels >= 0
        global_labels[rows[ok]] = [mapping[i] for i in labels[ok]]
        summary.update(parameter=config.parameter, value=value)
        points.append(summary)
    out = df.copy()
    out["attractor"] = global_labels
    out = out.drop(columns=["cycle", "scales"])
    if len(config.values) == 1:
        return points[0], out
    classes = sorted({c for p in points for c in p["fractions"]})
    for g in globals_:
        per_point = [next((e for e in p["attractors"] if e["global_id"] == g["id"]), None) for p in points]
        g["fractions"] = [e["fraction"] if e else 0.0 for e in per_point]
        g["stderr"] = [e["stderr"] if e else binomial_stderr(0.0, p["runs"]) for e, p in zip(per_point, points)]
        g["theta_absmax"] = [e["theta_absmax"] if e else None for e in per_point]
    summary = {
        "parameter": config.parameter,
        "values": list(config.values),
        "classes": {c: [p["fractions"].get(c, 0.0) for p in points] for c in classes},
        "classes_stderr": {
            c: [binomial_stderr(p["fractions"].get(c, 0.0), p["runs"]) for p in points] for c in classes
        },
        "unsettled_after_100": [p["unsettled_after_100"] for p in points],
        "unsettled_after_100_stderr": [p["unsettled_after_100_stderr"] for p in points],
        "irregular_after_100": [p["irregular_after_100"] for p in points],
        "irregular_after_100_stderr": [p["irregular_after_100_stderr"] for p in points],
        "escape_rate": [p["escape_rate"] for p in points],
        "attractors": globals_,
        "points": points,
    }
    return summary, out
