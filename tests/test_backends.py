"""The backend contract, checked on every registered backend."""

import numpy as np
import pytest

from pendsweep.backends import BACKENDS, Backend, BackendBase, make_backend
from pendsweep.backends.status import Status
from pendsweep.kernels import N_RECORD_COLUMNS
from pendsweep.kernels._layout import REC_THETA_SEC, REC_Y_SEC
from pendsweep.model.params import TABLE_IV

SEC = slice(REC_Y_SEC, REC_THETA_SEC + 2)  # y_sec, ydot_sec, theta_sec, thetadot_sec
POINTS = [TABLE_IV.replace(alpha=a, fe=f) for a, f in ((5.0, 2.2), (12.0, 2.5), (17.0, 2.45))]


@pytest.fixture(params=sorted(BACKENDS))
def backend(request):
    return make_backend(request.param)


def test_every_backend_is_registered_and_declares_the_contract(backend):
    assert isinstance(backend, Backend)
    assert BACKENDS[backend.name] is type(backend)
    assert isinstance(type(backend).batched, bool)
    assert make_backend(backend.name, **backend.options()) == backend


def test_steps_per_period_fit_whole_periods_near_dt(backend):
    for params in POINTS:
        n = backend.steps_per_period(params)
        dt = backend.options()["dt"]
        assert abs(n - 1.0 / (params.fe * dt)) <= 0.5  # the whole number of steps closest to dt


def test_section_reads_back_the_initial_coordinates_and_kick_moves_theta_only(backend):
    params = POINTS[0]
    state = backend.initial_state(params, 0.003, -0.02, 0.25, 1.5)
    np.testing.assert_array_equal(backend.section(state), [0.003, -0.02, 0.25, 1.5])
    before = state.copy()
    kicked = backend.kick(state, 0.1)
    np.testing.assert_array_equal(state, before)  # a new state; the argument is untouched
    assert kicked is not state and kicked.shape == state.shape
    np.testing.assert_array_equal(backend.section(kicked), [0.003, -0.02, 0.25 + 0.1, 1.5])
    # Everything that is not the pendulum angle stays as it was.
    np.testing.assert_array_equal(np.delete(kicked, 2), np.delete(state, 2))


def test_run_point_records_end_on_the_final_section(backend):
    params = POINTS[1]
    run = backend.run_point(params, backend.initial_state(params, 0, 0, 0.1, 0), 3, 4)
    assert run.status is Status.OK and run.periods_done == 7
    assert run.records.shape == (4, N_RECORD_COLUMNS) and np.isfinite(run.records).all()
    # The last record's stroboscopic section is the state the point ends in (theta wrapped),
    # as measured: a backend with an encoder records theta to one pulse.
    pulse = backend.options().get("encoder_resolution", 0.0)
    np.testing.assert_allclose(backend.section(run.state), run.records[-1, SEC], rtol=0, atol=1e-12 + pulse)


def test_run_points_equals_run_point_on_each(backend):
    states = np.array([backend.initial_state(q, 0, 0, th, 0) for q, th in zip(POINTS, (0.1, -0.4, 1.0))])
    many = backend.run_points(POINTS, states, 4, 3)
    assert len(many) == len(POINTS)
    for q, state, got in zip(POINTS, states, many):
        ref = backend.run_point(q, state, 4, 3)
        assert got.status is ref.status and got.periods_done == ref.periods_done
        if backend.batched:  # a vectorised kernel: the scalar kernel's numbers to rounding
            np.testing.assert_allclose(got.records, ref.records, rtol=1e-9, atol=1e-12)
        else:  # the documented fallback is run_point itself
            np.testing.assert_array_equal(got.records, ref.records)
            np.testing.assert_array_equal(got.state, ref.state)


def test_diverging_point_is_a_status_not_an_exception(backend):
    params = TABLE_IV.replace(alpha=1e300)
    run = backend.run_points([params], np.array([backend.initial_state(params, 0, 0, 0.1, 0)]), 2, 2)[0]
    assert run.status in (Status.DIVERGED, Status.UNSTABLE) and run.periods_done < 4


def test_the_fallback_is_declared_not_probed():
    assert BackendBase.batched is False
    assert BACKENDS["emulated"].batched is True
    assert BACKENDS["substructured"].batched is False
    for cls in BACKENDS.values():  # a batched backend brings the classifier's batched evidence too
        assert callable(getattr(cls, "evidence_many", None)) == cls.batched
