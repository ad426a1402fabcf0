"""Basin map with early stop: the issue-14 target (200 x 200 starts, 1000-period cap, <= 60 s on 2 cores)."""

from __future__ import annotations

import resource
import time

import numpy as np

from ..backends._batch import run_batch
from ..basins import BasinConfig, run_basins
from .registry import benchmark


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


@benchmark("basins")
def bench_basins(quick: bool) -> dict:
    """Wall and CPU time of a basin grid at alpha = 40 N, against the same starts without early stop.

    The peer (every start integrated to the cap) is timed on a subsample of
    starts for the full cap and scaled by starts; the ratio is the saving
    of early stop. CPU seconds are reported beside wall seconds because the
    machine is shared: CPU / 2 is what two idle cores would need.
    """
    grid = (50, 50) if quick else (200, 200)
    max_periods = 1000
    config = BasinConfig("alpha", (40.0,), {"fe": 2.5}, sampling="grid", grid=grid, max_periods=max_periods)
    params = config.params_at(40.0)
    run_batch([params] * 2, np.zeros((2, 4)), 0, 1)  # load the JIT cache

    cpu0, t0 = _cpu_seconds(), time.perf_counter()
    df = run_basins(config, None)
    wall, cpu = time.perf_counter() - t0, _cpu_seconds() - cpu0

    sample = 256
    theta0, thetadot0 = config.initial_conditions(0)
    states = np.zeros((sample, 4))
    states[:, 2], states[:, 3] = theta0[:sample], thetadot0[:sample]
    peer_periods = 100 if quick else 250  # a quarter of the cap, scaled up below
    cpu1, t1 = _cpu_seconds(), time.perf_counter()
    run_batch([params] * sample, states, 0, peer_periods)
    peer_wall = (time.perf_counter() - t1) * (config.starts / sample) * (max_periods / peer_periods)
    peer_cpu = (_cpu_seconds() - cpu1) * (config.starts / sample) * (max_periods / peer_periods)
    periods = df["periods_done"].to_numpy()
    return {
        "starts": config.starts,
        "max_periods": max_periods,
        "wall_seconds": wall,
        "cpu_seconds": cpu,
        "target_wall_seconds_two_cores": 60.0,
        "mean_periods_per_start": float(periods.mean()),
        "unsettled_fraction": float((df["motion"] == "unsettled").mean()),
        "no_early_stop_wall_seconds_estimated": peer_wall,
        "no_early_stop_cpu_seconds_estimated": peer_cpu,
        "early_stop_saving_cpu": peer_cpu / cpu,
        "ns_per_start_period_cpu": cpu / periods.sum() * 1e9,
    }
