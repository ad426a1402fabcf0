"""Basins and maps against their kernel: the cost of a point-step inside ``basins`` and ``map``.

``basins`` and ``map`` integrate their starts (cells) in rounds on the
batched kernel and check between rounds which have settled
(:func:`pendsweep.studies.basins.settle_runs`). The kernel's own cost per point-step
is measured in the same run on the same starts (a fixed horizon, no checks);
the ratio of the two is the overhead of the rounds, the settling checks and
the bookkeeping (goal: at most 1.2). The saving of early stop is reported
against the same starts all integrated to the cap (the naive per-start
alternative, timed on a subsample and scaled). The rounds' own cost for a
GPU-sized unit (131,072 starts) is timed with the kernel replayed from
stored records: the part of a GPU basin map that the GPU cannot speed up.
"""

from __future__ import annotations

import resource
import time

import numpy as np

from ..backends._base import steps_per_period
from ..backends._batch import run_batch
from ..studies.basins import BasinConfig, run_basins
from ..studies.maps import MapConfig, run_map
from .registry import benchmark

#: Largest cost of a point-step in basins and map over the kernel's own (issue 23).
OVERHEAD_MAX = 1.2


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _timed(fn):
    cpu0, t0 = _cpu_seconds(), time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0, _cpu_seconds() - cpu0


def _kernel_ns(params: list, states: np.ndarray, periods: int) -> float:
    """CPU ns per point-step of the batched kernel alone on ``params`` from ``states``, ``periods`` each."""
    run_batch(params[:2], states[:2], 0, 1)  # load the JIT cache
    _, _, cpu = _timed(lambda: run_batch(params, states, 0, periods))
    steps = sum(steps_per_period(p.fe, 1e-3) for p in params) * periods
    return 1e9 * cpu / steps


class _Replay:
    """A stroboscopic map whose 'integration' replays stored records: only the rounds' host work costs time."""

    def __init__(self, system, bank: np.ndarray):
        self.system, self.bank, self.done = system, bank, 0

    def advance(self, states, periods, ids):
        records = np.ascontiguousarray(self.bank[ids % len(self.bank), self.done : self.done + periods])
        self.done += periods  # every run of a round has done as many periods
        return records, states, np.zeros(len(ids), dtype=np.int64)

    def scales_for(self, ids, records):
        return self.system.scales_for(ids, records)


def rounds_host_seconds(config: BasinConfig, distinct: int, starts: int) -> dict:
    """The rounds' own cost (settling checks, history, bookkeeping) for ``starts`` starts, the kernel replayed.

    ``distinct`` starts of the grid are integrated to the cap once; a GPU's
    unit of ``starts`` then replays their records, so what is timed is what
    a GPU cannot speed up.
    """
    from ..studies.basins import EmulatedMap, settle_runs

    params = config.params_at(config.values[0])
    theta0, thetadot0 = config.initial_conditions(0)
    states = np.zeros((distinct, 4))
    states[:, 2], states[:, 3] = theta0[:distinct], thetadot0[:distinct]
    bank = run_batch([params] * distinct, states, 0, config.max_periods).records
    system = EmulatedMap((params,))
    settle_runs(_Replay(system, bank), np.zeros((distinct, 4)), config.max_periods)  # JIT caches loaded
    runs, wall, _ = _timed(lambda: settle_runs(_Replay(system, bank), np.zeros((starts, 4)), config.max_periods))
    return {
        "starts": starts,
        "replayed_from_starts": distinct,
        "seconds": wall,
        "ns_per_start_period": 1e9 * wall / float(runs.periods_done.sum()),
    }


@benchmark("basins")
def bench_basins(quick: bool) -> dict:
    """Basin grid at alpha = 40 N and a (alpha, fe) map: ns per point-step against the kernel's, early stop's saving."""
    grid = (50, 50) if quick else (200, 200)
    max_periods = 1000
    config = BasinConfig("alpha", (40.0,), {"fe": 2.5}, sampling="grid", grid=grid, max_periods=max_periods)
    params = config.params_at(40.0)
    steps = steps_per_period(params.fe, 1e-3)  # basins run at the emulated backend's 1 ms step
    run_batch([params] * 2, np.zeros((2, 4)), 0, 1)  # load the JIT cache

    df, wall, cpu = _timed(lambda: run_basins(config, None))
    periods = df["periods_done"].to_numpy()
    basins_ns = 1e9 * cpu / (periods.sum() * steps)

    sample = 1024 if quick else 4096
    theta0, thetadot0 = config.initial_conditions(0)
    states = np.zeros((sample, 4))
    states[:, 2], states[:, 3] = theta0[:sample], thetadot0[:sample]
    peer_periods = 50 if quick else 100
    kernel_ns = _kernel_ns([params] * sample, states, peer_periods)
    peer_cpu = kernel_ns * 1e-9 * config.starts * max_periods * steps  # every start to the cap

    host = rounds_host_seconds(config, 256 if quick else 1024, 8192 if quick else 131072)

    side = 20 if quick else 60
    map_config = MapConfig(
        "alpha", tuple(np.linspace(5.0, 40.0, side)), "fe", tuple(np.linspace(2.2, 2.8, side)), max_periods=600
    )
    cells, map_wall, map_cpu = _timed(lambda: run_map(map_config, None))
    cell_params = [map_config.params_at(a, f) for a, f in zip(cells["alpha"], cells["fe"])]
    cell_steps = np.array([steps_per_period(p.fe, map_config.dt) for p in cell_params])
    map_ns = 1e9 * map_cpu / float((cells["periods_done"].to_numpy() * cell_steps).sum())
    map_states = np.tile([0.0, 0.0, *map_config.initial], (len(cell_params), 1))
    map_kernel_ns = _kernel_ns(cell_params, map_states, peer_periods // 2)
    return {
        "starts": config.starts,
        "max_periods": max_periods,
        "wall_seconds": wall,
        "cpu_seconds": cpu,
        "mean_periods_per_start": float(periods.mean()),
        "unsettled_fraction": float((df["motion"] == "unsettled").mean()),
        "basins_ns_per_point_step_cpu": basins_ns,
        "kernel_ns_per_point_step_cpu": kernel_ns,
        "basins_over_kernel": basins_ns / kernel_ns,
        "no_early_stop_cpu_seconds_estimated": peer_cpu,
        "early_stop_saving_cpu": peer_cpu / cpu,
        "map": {
            "cells": len(cell_params),
            "max_periods": map_config.max_periods,
            "wall_seconds": map_wall,
            "cpu_seconds": map_cpu,
            "map_ns_per_point_step_cpu": map_ns,
            "kernel_ns_per_point_step_cpu": map_kernel_ns,
            "map_over_kernel": map_ns / map_kernel_ns,
        },
        "rounds_host_with_replayed_kernel": host,
        "targets": {"over_kernel_max": OVERHEAD_MAX, "basins_200x200_wall_seconds_max": 10.0},
    }
