"""Diagnosis of a 60 s, 1 kHz record with every applicable candidate (target < 30 s)."""

from __future__ import annotations

from ..measured.diagnose import Replay, diagnose, synthesize
from ..model.params import FIG9_PO, TABLE_IV
from .registry import benchmark, best_of


@benchmark("measured")
def bench_measured(quick: bool) -> dict:
    """Seconds to diagnose forced and free-decay records, and per nominal replay (the peer)."""
    duration = 6.0 if quick else 60.0
    out: dict = {"record_seconds": duration, "rate_hz": 1000.0, "target_seconds": 30.0}
    cases = {
        "forced": synthesize(
            "forced",
            FIG9_PO,
            {"oscillator_damping": 26.0},
            duration,
            1000.0,
            seed=0,
            theta_init=0.3,
            transient=20.0,
            tone2=(2.0, 1.3),
        ),
        "substructured": synthesize(
            "substructured",
            FIG9_PO,
            {"actuator_delay": 0.008},
            duration,
            1000.0,
            seed=0,
            theta_init=0.3,
            transient=20.0,
            tone2=(2.0, 1.3),
        ),
        "free_decay": synthesize("free_decay", TABLE_IV, {"viscous_damping": 1.8e-4}, duration, 1000.0, seed=0),
    }
    for kind, record in cases.items():
        replay = Replay(record)
        diagnose(Replay(synthesize(kind, record.params, {}, 2.0, 100.0, theta_init=0.3, transient=1.0)))  # load kernels
        t_diag = best_of(lambda replay=replay: diagnose(replay), 1)
        t_sim = best_of(lambda replay=replay: replay.simulate(replay.nominal), 5)
        d = diagnose(replay)
        out[kind] = {
            "candidates": len(d.candidates),
            "diagnose_seconds": t_diag,
            "nominal_replay_seconds": t_sim,
            "diagnose_in_replays": t_diag / t_sim,
            "cause": d.cause,
            "under_target": t_diag < 30.0,
        }
    return out
