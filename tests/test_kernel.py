"""Physics of the emulated RK4 kernel: order, invariants, analytic limits."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pendsweep import FIG9_CO, TABLE_IV, Status, make_backend
from pendsweep.kernels import PHYSICS, eq11_params, wrap_angle
from pendsweep.kernels._layout import RECORD_INDEX as REC
from pendsweep.model.analytic import linear_amplitude, mechanical_energy

SMOOTH = TABLE_IV.replace(b1=0.0, b3=0.0, alpha=8.0, fe=2.5)


def final_state(params, dt, periods, state0, signum="step"):
    backend = make_backend("emulated", dt=dt, signum=signum)
    trace = backend.trace(params, np.array(state0, float), periods)
    return trace.iloc[-1][["y", "ydot", "theta", "thetadot"]].to_numpy()


def reference(params, periods, state0):
    """DOP853 at tight tolerance, the same right-hand side (smooth damping)."""
    q = eq11_params(params.kernel_array(), False, False)

    def rhs(t, z):
        force = params.alpha * math.sin(params.omega_e * t)
        return PHYSICS.eq11_rhs(tuple(z), (force, 0.0), q)

    sol = solve_ivp(rhs, (0, periods / params.fe), state0, method="DOP853", rtol=1e-13, atol=1e-13)
    return sol.y[:, -1]


def test_rk4_converges_with_order_four():
    state0 = [0.01, 0.0, 1.0, 0.0]
    periods = 5
    ref = reference(SMOOTH, periods, state0)
    scale = np.array([0.01, 0.2, 1.0, 5.0])  # typical magnitudes of y, ydot, theta, thetadot
    dts = np.array([8e-3, 4e-3, 2e-3, 1e-3])
    errors = [np.max(np.abs(final_state(SMOOTH, dt, periods, state0) - ref) / scale) for dt in dts]
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert 3.7 <= slope <= 4.3, (slope, errors)
    assert errors[-1] < 1e-8


def test_energy_is_conserved_without_damping_and_forcing():
    free = TABLE_IV.replace(b1=0.0, b2=0.0, b3=0.0, C=0.0, alpha=0.0, fe=1.0)
    backend = make_backend("emulated", dt=1e-3)
    trace = backend.trace(free, np.array([0.01, 0.0, 1.0, 0.5]), 10)  # 10 s at fe = 1 Hz
    energy = mechanical_energy(free, trace.y, trace.ydot, trace.theta, trace.thetadot).to_numpy()
    drift = np.max(np.abs(energy - energy[0])) / abs(energy[0])
    assert drift < 1e-6
    assert np.ptp(trace.theta) > 1.5  # the pendulum really swings and exchanges energy


@pytest.mark.parametrize("fe", [1.8, 2.5, 3.2])
def test_pendulum_at_rest_gives_linear_oscillator_amplitude(emulated, fe):
    params = TABLE_IV.replace(alpha=10.0, fe=fe)
    run = emulated.run_point(params, np.zeros(4), 100, 20)
    assert run.status is Status.OK
    assert np.all(run.records[:, REC["theta_absmax"]] == 0.0)  # theta stays exactly 0
    amplitude = run.records[:, REC["y_absmax"]].max()
    assert amplitude == pytest.approx(linear_amplitude(params), rel=5e-3)


def test_signum_per_stage_differs_only_at_order_dt(emulated):
    params = TABLE_IV.replace(alpha=5.0, fe=2.2)
    state = np.array([0.0, 0.0, 0.1, 0.0])
    a = emulated.run_point(params, state, 0, 10).records
    b = make_backend("emulated", signum="stage").run_point(params, state, 0, 10).records
    diff = np.max(np.abs(a[:, 1] - b[:, 1]))
    assert 0 < diff < 1e-3


def test_divergence_is_a_status_not_a_crash(emulated):
    params = TABLE_IV.replace(alpha=1e300)
    run = emulated.run_point(params, np.array([0.0, 0.0, 0.1, 0.0]), 2, 3)
    assert run.status is Status.DIVERGED
    assert np.isnan(run.records).all()
    assert run.periods_done < 5


def test_rotations_are_counted_and_peaks_wrapped(emulated):
    params = TABLE_IV.replace(b1=0.0, b2=0.0, b3=0.0, alpha=0.0, fe=1.0)
    state = np.array([0.0, 0.0, 0.0, 20.0])  # enough energy to go over the top
    run = emulated.run_point(params, state, 0, 3)
    trace = emulated.trace(params, state, 3)
    # Net passes over the top equal the unwrapped angle's wrap count.
    expected = math.ceil((trace.theta.iloc[-1] - math.pi) / (2 * math.pi))
    assert run.records[:, REC["rotations"]].sum() == expected >= 3
    assert np.all(np.abs(run.records[:, REC["theta_peak"]]) <= math.pi)
    assert np.all(np.abs(run.records[:, REC["theta_sec"]]) <= math.pi)


def test_wrap_angle_range():
    x = np.linspace(-20, 20, 10001)
    w = np.array([wrap_angle(v) for v in x])
    assert np.all(w > -math.pi) and np.all(w <= math.pi)
    assert np.allclose(np.cos(w), np.cos(x)) and np.allclose(np.sin(w), np.sin(x))


def test_physics_source_compiles_for_another_target():
    """The right-hand sides are plain functions: compiled for pure Python here (the GPU backend
    compiles the same source for CUDA), one RK4 step agrees with the numba CPU step bit for bit."""
    from pendsweep.kernels import compile_physics
    from pendsweep.kernels._rk4 import make_rk4_step
    from pendsweep.kernels._steps import eq11_rk4

    def python(fn):
        return fn

    plain = compile_physics(python)
    step = make_rk4_step(plain.eq11_rhs, python)
    q = eq11_params(FIG9_CO.kernel_array(), False, False)
    x = (0.01, -0.02, 0.7, 1.3)
    u = (3.0, 1.0), (3.5, 1.0), (4.0, 1.0)
    assert step(x, *u, 1e-3, q) == eq11_rk4(x, *u, 1e-3, q)
    assert plain.eq11_rhs(x, u[0], q) != plain.eq11_rhs(x, (3.0, -1.0), q)  # the held sign enters
