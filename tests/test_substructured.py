"""The substructured backend against the emulated system, the paper and theory."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pendsweep.backends import make_backend
from pendsweep.engine.results import read_results
from pendsweep.errors import ConfigError
from pendsweep.hybrid.sync import sync_ratio, xcorr_delay
from pendsweep.hybrid.trace import run_trace
from pendsweep.kernels import RECORD_COLUMNS
from pendsweep.kernels._layout import RECORD_INDEX as REC
from pendsweep.model.loop import (
    effective_delay,
    filter_phase,
    phase_to_delay,
    predictor_weights,
)
from pendsweep.model.params import ENCODER_RESOLUTION, FIG9_PO, FIG11A
from pendsweep.studies.sweep import SweepConfig, run_sweep

QUIET = dict(
    force_noise=0.0, harmonic3=0.0, harmonic5=0.0, harmonic7=0.0,
    encoder_resolution=0.0, lvdt_resolution=0.0, lvdt_noise=0.0,
)  # fmt: skip


def test_fig9_po_split_is_the_issue_case():
    assert (FIG9_PO.alpha, FIG9_PO.fe, FIG9_PO.M, FIG9_PO.M1, FIG9_PO.M2) == (5.0, 2.2, 10.9, 10.0, 0.9)
    assert (FIG9_PO.C, FIG9_PO.C1, FIG9_PO.C2) == (20.0, 10.0, 10.0)


def test_consistency_limit_converges_at_first_order():
    """Ideal actuator, no noise: y* -> emulated y as dt shrinks, error ~ dt (force one step old)."""
    p = FIG9_PO
    periods = 22  # 10 s at 2.2 Hz
    n0 = 455  # ticks per period at dt = 1 ms
    fine = make_backend("emulated", dt=1 / (p.fe * 8 * n0))
    ref = fine.trace(p, fine.initial_state(p, 0, 0, 0.1, 0), periods)["y"].to_numpy()
    steps, errors = [], []
    for factor in (1, 2, 4):
        n = n0 * factor
        b = make_backend("substructured", actuator="ideal", predictor_order=-1, dt=1 / (p.fe * n), **QUIET)
        y = b.trace(p, b.initial_state(p, 0, 0, 0.1, 0), periods)["y"].to_numpy()
        y_ref = ref[:: 8 // factor][: y.size]
        steps.append(1 / (p.fe * n))
        errors.append(np.max(np.abs(y - y_ref)) / np.max(np.abs(y_ref)))
    assert errors[0] < 0.02, f"dt = 1 ms: max |y* - y| is {100 * errors[0]:.2f} % of the amplitude"
    order = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert order > 0.9, f"fitted convergence order {order:.3f}, errors {errors}"
    assert errors[2] < errors[1] < errors[0]


def test_default_total_delay_is_18ms_and_is_the_measured_lag():
    b = make_backend("substructured")
    for fe in (2.2, 2.5):
        assert 0.0175 < b.effective_delay(fe) < 0.0185
    assert b.horizon(FIG9_PO) == b.effective_delay(FIG9_PO.fe)
    # Linear regime (pendulum at rest), no prediction: the cross-correlation lag of
    # x behind y* is the documented total (transport + hold + servo phase lag).
    p = FIG9_PO.replace(alpha=1.0)
    for opts in ({}, {"actuator": "delay", "transport_delay": 0.012}, {"transport_delay": 0.0}):
        b = make_backend("substructured", predictor_order=-1, **opts, **QUIET)
        df = run_trace(b, p, (0, 0, 0, 0), transient_periods=60, periods=22)
        lag = xcorr_delay(df["y"], df["x"], df["t"].iloc[1])
        assert lag == pytest.approx(b.effective_delay(p.fe), abs=5e-5), opts
    assert effective_delay("ideal", 0.01, 30, 0.7, 1e-3, 2.2) == 0.0


def test_table_i_po_ratio_with_and_without_prediction():
    """Default transfer system (18 ms), paper-level noise: < 5 % with 1st-order 5-point prediction."""
    p = FIG9_PO
    ratios = {}
    for label, order in (("predicted", 1), ("none", -1)):
        b = make_backend("substructured", predictor_order=order, predictor_points=5)
        df = run_trace(b, p, transient_periods=100, periods=22)
        assert df.attrs["status"] == "ok"
        ratios[label] = sync_ratio(df["y"], df["x_meas"])
    assert ratios["predicted"] < 5.0, ratios  # paper: 3.9 %
    assert ratios["none"] > 3 * ratios["predicted"], ratios


def _critical_transport_delay(p, bandwidth=30.0, zeta=0.7) -> float:
    """Smallest pure delay destabilising 1 + F_s N_m G e^{-s tau} = 0 (Eq. 9 with the servo)."""
    w = np.linspace(1.0, 200.0, 400001)
    s = 1j * w
    ws = 2 * np.pi * bandwidth
    loop = (
        ((p.M2 + p.m) * s**2 + p.C2 * s) / (p.M1 * s**2 + p.C1 * s + p.K) * ws**2 / (s**2 + 2 * zeta * ws * s + ws**2)
    )
    cross = np.where(np.diff(np.sign(np.abs(loop) - 1.0)) != 0)[0]
    taus = [((np.pi + np.angle(loop[i])) % (2 * np.pi)) / w[i] for i in cross]
    return min(taus)


def test_delay_instability_is_a_status_not_a_crash(tmp_path):
    p = FIG9_PO
    # Subtract the hold (dt/2) the loop adds on top of the transport delay.
    critical = _critical_transport_delay(p) - 0.5e-3
    assert 0.15 < critical < 0.25
    for factor, expected in ((0.8, "ok"), (1.3, "unstable")):
        b = make_backend("substructured", predictor_order=-1, transport_delay=factor * critical)
        run = b.run_point(p, b.initial_state(p, 0, 0, 0.1, 0), 100, 20)
        assert run.status.value == expected, (factor, critical, run.periods_done)
        assert np.all(np.isfinite(run.records)) and np.all(np.isfinite(run.state))
    config = SweepConfig(
        parameter="alpha", values=(4.0, 5.0), model=p.to_dict(), backend="substructured",
        backend_options={"predictor_order": -1, "transport_delay": 1.3 * critical},
        transient_periods=20, record_periods=5,
    )  # fmt: skip
    run_sweep(config, tmp_path / "unstable.parquet")
    df, _ = read_results(tmp_path / "unstable.parquet")
    assert set(df["status"]) == {"unstable"}
    assert np.all(np.isfinite(df[list(RECORD_COLUMNS)].to_numpy()))


def test_servo_with_prediction_stays_bounded_at_18ms():
    """The paper's rig (servo, 18 ms, first-order prediction) runs 120 periods without tripping.

    A bare delay with prediction used to trip here too; that came from the Hermite lookup at each
    substep's midpoint, which extrapolated a segment's cubic past its knot (issue 32 removed it; see
    docs/continuation.md, "What is doubtful").
    """
    p = FIG9_PO
    servo = make_backend("substructured", **QUIET)
    assert servo.run_point(p, servo.initial_state(p, 0, 0, 0.1, 0), 100, 20).status.value == "ok"


def test_same_seed_same_bytes_and_noise_never_replays():
    p = FIG9_PO
    runs = []
    for seed in (7, 7, 8):
        b = make_backend("substructured", seed=seed)
        runs.append(b.run_point(p, b.initial_state(p, 0, 0, 0.1, 0), 5, 5))
    assert runs[0].records.tobytes() == runs[1].records.tobytes()
    assert runs[0].state.tobytes() == runs[1].state.tobytes()
    assert runs[0].state.tobytes() != runs[2].state.tobytes()
    b = make_backend("substructured", seed=7)
    t1 = b.trace(p, b.initial_state(p, 0, 0, 0.1, 0), 3)
    t2 = b.trace(p, b.initial_state(p, 0, 0, 0.1, 0), 3)
    assert t1.to_numpy().tobytes() == t2.to_numpy().tobytes()
    # The noise seed advances with the ticks done, so a continued state sees new noise.
    assert runs[0].state[6] == 10 * b.steps_per_period(p)
    noise_a = t1["Fs"] - t1["Fs_true"]
    later = b.trace(p, runs[0].state, 3)
    noise_b = later["Fs"] - later["Fs_true"]
    assert not np.allclose(noise_a.to_numpy(), noise_b.to_numpy())


def test_validation_names_the_bad_numbers():
    b = make_backend("substructured")
    with pytest.raises(ConfigError, match=r"M1 = -0.4 kg.*C1 = 10 kg/s"):
        b.validate(FIG9_PO.replace(M=0.5))
    with pytest.raises(ConfigError, match=r"C1 = -5 kg/s"):
        b.validate(FIG9_PO.replace(C=5.0))
    for bad in (
        {"actuator": "hydraulic"},
        {"predictor_order": 5},
        {"predictor_order": 2, "predictor_points": 2},
        {"transport_delay": -0.001},
        {"filter_low": 4.0, "filter_high": 3.0},
        {"physics_substeps": 0},
    ):
        with pytest.raises(ConfigError):
            make_backend("substructured", **bad)
    with pytest.raises(ConfigError, match="outside the force filter"):
        make_backend("substructured", force_filter=True).validate(FIG9_PO.replace(fe=5.0))


def test_sweep_records_match_the_emulated_schema():
    base = dict(
        parameter="alpha", values=(16.0, 20.0, 24.0), model=FIG11A.to_dict(), transient_periods=10, record_periods=3
    )
    emu = run_sweep(SweepConfig(**base))
    sub = run_sweep(SweepConfig(**base, backend="substructured"))
    # The rig's sensors are noisy: the classifier's measured noise follows the emulated schema's columns.
    noise_columns = ["section_noise", "periodic_tol"]
    assert list(sub.columns) == list(emu.columns) + noise_columns
    assert list(sub.dtypes) == list(emu.dtypes) + [np.dtype("float64")] * 2
    assert len(sub) == len(emu) and set(sub["status"]) == {"ok"}
    # theta is the encoder angle theta_x: a whole number of pulses (up to wrapping)
    pulses = sub["theta_peak"].to_numpy() / ENCODER_RESOLUTION
    wrapped = np.abs(np.abs(sub["theta_peak"]) - np.pi) < ENCODER_RESOLUTION
    assert np.allclose(pulses[~wrapped], np.round(pulses[~wrapped]), atol=1e-6)


@pytest.mark.parametrize("order,points", [(0, 1), (1, 5), (2, 3), (3, 7), (4, 5)])
def test_predictor_is_exact_for_polynomials_of_its_order(order, points):
    dt, horizon = 1e-3, 0.018
    w, wd = predictor_weights(order, points, horizon, dt)
    coeffs = np.arange(1.0, order + 2.0)
    t = -dt * np.arange(points)
    samples = np.polyval(coeffs[::-1], t)
    assert w @ samples == pytest.approx(np.polyval(coeffs[::-1], horizon), rel=1e-9)
    assert wd @ samples == pytest.approx(np.polyval(np.polyder(coeffs[::-1]), horizon), rel=1e-7)


def test_filter_phase_is_an_equivalent_delay():
    assert 1e3 * phase_to_delay(-0.2185, 2.2) == pytest.approx(15.8, abs=0.05)  # the paper's example
    b = make_backend("substructured", force_filter=True)
    dt = b.step(FIG9_PO)
    phase = filter_phase(b.filter_sos(FIG9_PO), FIG9_PO.fe, dt)
    assert b.filter_delay(FIG9_PO) == pytest.approx(-phase / (2 * math.pi * FIG9_PO.fe))
    # The filtered, forward-predicted force keeps the PO test accurate.
    df = run_trace(b, FIG9_PO, transient_periods=100, periods=22)
    emu = run_trace(make_backend("emulated"), FIG9_PO, transient_periods=100, periods=22)
    assert sync_ratio(df["y"], df["x_meas"]) < 5.0
    assert df["y"].abs().max() == pytest.approx(emu["y"].abs().max(), rel=0.05)


def test_kick_moves_the_true_pendulum():
    b = make_backend("substructured", **QUIET)
    state = b.initial_state(FIG9_PO, 0, 0, 0.0, 0)
    assert np.all(b.run_point(FIG9_PO, state, 5, 2).records[:, REC["theta_absmax"]] == 0.0)
    state[2] += 0.1
    assert np.all(b.run_point(FIG9_PO, state, 0, 1).records[:, REC["theta_absmax"]] > 0.05)


def test_sweep_seed_reaches_the_backend_noise():
    base = dict(
        parameter="alpha",
        values=(5.0,),
        model=FIG9_PO.to_dict(),
        backend="substructured",
        transient_periods=2,
        record_periods=2,
    )
    assert SweepConfig(**base, seed=11).make_backend().seed == 11
    assert SweepConfig(**base, seed=11, backend_options={"seed": 3}).make_backend().seed == 3
    a, b = (run_sweep(SweepConfig(**base, seed=s)) for s in (1, 2))
    assert not np.array_equal(a["y_sec"].to_numpy(), b["y_sec"].to_numpy())


@pytest.mark.parametrize("options", [{}, {"force_filter": True}, {"actuator": "delay", "transport_delay": 0.005}])
def test_continuing_a_state_is_seamless(options):
    """Without noise, 6 periods in one call and 3 + 3 in two calls give the same bytes."""
    b = make_backend("substructured", **QUIET, **options)
    s0 = b.initial_state(FIG9_PO, 0, 0, 0.1, 0)
    one = b.run_point(FIG9_PO, s0, 3, 3)
    half = b.run_point(FIG9_PO, s0, 3, 0)
    two = b.run_point(FIG9_PO, half.state, 0, 3)
    assert one.state.tobytes() == two.state.tobytes()
    assert one.records.tobytes() == two.records.tobytes()
