"""The compiled settling checks (kernels._settle) against the straightforward numpy ones, outcome by outcome."""

import sys
from pathlib import Path

import numpy as np
import pytest

from pendsweep.analysis.attractors import (
    MATCH_TOL,
    ROTATION_WINDOW,
    SETTLE_TOL,
    SETTLE_WINDOW,
    section_scales_many,
    settling,
)
from pendsweep.analysis.sections import MAX_PERIOD
from pendsweep.backends._batch import run_batch
from pendsweep.kernels._layout import REC_ROTATIONS, REC_THETA_ABSMAX, REC_THETA_SEC, REC_Y_SEC
from pendsweep.kernels._settle import update_near_since
from pendsweep.model.params import ENCODER_RESOLUTION, TABLE_IV

sys.path.insert(0, str(Path(__file__).parent))
import settle_reference  # noqa: E402

OPTIONS = dict(
    tol=SETTLE_TOL, window=SETTLE_WINDOW, max_period=MAX_PERIOD, rest_threshold=ENCODER_RESOLUTION,
    rotation_window=ROTATION_WINDOW,
)  # fmt: skip


@pytest.fixture(scope="module")
def records():
    """Basin-like runs with every outcome: rest, periodic-1 and -2, rotations, chaos, a divergence, ties.

    Starts over theta0 at alpha = 40 N and fe = 2.5 Hz (coexisting rest, swinging and rotating
    attractors, chaotic transients), 160 periods each, plus edited copies: a diverged tail (NaN),
    a section moved by just under and just over the tolerance, a period-4 cycle with a near period-2.
    """
    params = TABLE_IV.replace(alpha=40.0, fe=2.5)
    k = 96
    states = np.zeros((k, 4))
    states[:, 2] = np.linspace(-np.pi, np.pi, k)
    states[:, 3] = np.linspace(-12.0, 12.0, k)[::-1]
    recs = run_batch([params] * k, states, 0, 160).records.copy()
    diverged = recs[:4].copy()
    diverged[:, -7:] = np.nan
    edged = np.repeat(recs[:1], 4, axis=0)
    scale_y = section_scales_many(edged, params.omega_e, params.omega_p)[0, 0]
    for i, factor in enumerate((0.999, 1.001, 0.5 * MATCH_TOL / SETTLE_TOL, 3.0)):
        edged[i, -5, REC_Y_SEC] += factor * SETTLE_TOL * scale_y
    spiral = np.repeat(recs[:1], 2, axis=0)
    alternate = (np.arange(spiral.shape[1]) % 4 >= 2)[None, :]
    spiral[:, :, REC_THETA_SEC] += np.where(alternate, 0.02, 0.0) * np.array([[1.0], [0.001]])
    settled_run = int(
        np.flatnonzero(
            settling(
                recs, section_scales_many(recs[:, -SETTLE_WINDOW:], params.omega_e, params.omega_p), **OPTIONS
            ).period
            == 2
        )[0]
    )
    rest = recs[settled_run : settled_run + 1].copy()
    rest[:, :, REC_THETA_ABSMAX] = 0.1 * ENCODER_RESOLUTION  # a swing below one encoder pulse: at rest
    across_pi = recs[:1].copy()  # a swing whose section sits at theta = +-pi: a repeat only once wrapped
    across_pi[:, :, REC_Y_SEC : REC_Y_SEC + 4] = (1e-3, 0.0, 0.0, 0.0)
    across_pi[:, :, REC_THETA_SEC] = np.where(np.arange(recs.shape[1]) % 2 == 0, np.pi - 1e-5, -np.pi + 1e-5)
    across_pi[:, :, REC_ROTATIONS] = 0.0
    turns = np.repeat(recs[:1], 2, axis=0)
    turns[0, :, REC_ROTATIONS] = 1.0
    turns[1, :, REC_ROTATIONS] = np.where(np.arange(turns.shape[1]) == 150, 2.0, 1.0)
    return np.ascontiguousarray(np.concatenate([recs, diverged, edged, spiral, rest, across_pi, turns])), params


@pytest.mark.parametrize("length", [10, SETTLE_WINDOW, 60, 130, 160])
def test_compiled_settling_is_the_numpy_settling(records, length):
    recs, params = records
    rec = np.ascontiguousarray(recs[:, :length])
    scales = section_scales_many(rec[:, -SETTLE_WINDOW:], params.omega_e, params.omega_p)
    fast = settling(rec, scales, **OPTIONS)
    slow = settle_reference.settling(rec, scales, **OPTIONS)
    for name in ("settled", "period", "turns", "onset", "at_rest", "ambiguous"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name), err_msg=name)
    if length == 160:  # the fixture does reach every outcome
        assert {"semi-trivial", "unsettled", "rotating"} <= set(fast.motion) and fast.ambiguous.any()
        assert any(m.startswith("periodic") for m in fast.motion) and fast.motion[-3] == "periodic-1"


def test_compiled_near_since_is_the_numpy_bookkeeping(records):
    recs, params = records
    k = recs.shape[0]
    fast = np.zeros((k, MAX_PERIOD), dtype=np.int64)
    slow = fast.copy()
    active = np.arange(k)
    history_rows = max(SETTLE_WINDOW + MAX_PERIOD, ROTATION_WINDOW)
    for start in range(0, recs.shape[1], 20):  # rounds of 20 periods with the history the basin engine keeps
        buffer = np.ascontiguousarray(recs[:, max(0, start - history_rows) : start + 20])
        first_row = start + 20 - buffer.shape[1]
        scales = section_scales_many(buffer[:, -SETTLE_WINDOW:], params.omega_e, params.omega_p)
        update_near_since(buffer, scales, 20, first_row, MATCH_TOL, fast, active)
        settle_reference.near_since_update(buffer, scales, 20, first_row, MATCH_TOL, slow, active, MAX_PERIOD)
        np.testing.assert_array_equal(fast, slow)
    assert len(np.unique(fast)) > 10 and fast.max() <= recs.shape[1]  # a range of onsets, none past the end
