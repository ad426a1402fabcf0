"""Diagnosis of substructured tests part by part: the transfer system, the specimen, the numerical model (issue 22).

Records come from :mod:`pendsweep.measured.diagnose.testbench` (servo rigs written
independently of the replays: first- and second-order servos behind transport
delays, commands ramped or held, forward predictors, load-cell lags,
central-difference controllers), from analytic steady states, and from real
`pendsweep site` sessions driven by pendsweep's own client over TCP.
"""

import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from pendsweep.cli import main
from pendsweep.engine.results import METADATA_KEY, read_metadata
from pendsweep.errors import ConfigError
from pendsweep.kernels._measured import transfer_trace
from pendsweep.measured.diagnose.identify.servo_step import servo_propagator
from pendsweep.measured.diagnose.identify.transfer import Actuator, identify_transfer
from pendsweep.measured.diagnose.judge import BANDWIDTH_TOLERANCE, judge_transfer
from pendsweep.measured.diagnose.pipeline import diagnose_records
from pendsweep.measured.diagnose.testbench import TEST_SEEDS, Case, Rig, generate
from pendsweep.measured.records import Record, read_record, write_record
from pendsweep.model.params import FIG9_PO

sys.path.insert(0, str(Path(__file__).parent))
from site_helpers import ThreadSite  # noqa: E402

SEED = TEST_SEEDS[0] + 2201


def servo_case(effects=None, rig=None, rate=500.0, seed=SEED, duration=10.0):
    rig = rig or Rig()
    return Case("substructured", effects or {}, rate=rate, seed=seed, theta_init=0.3, duration=duration, rig=rig)


def verdict(case):
    d = diagnose_records([generate(case)])
    return d, d.to_json()


# -- the transfer models against exact solutions ---------------------------------------------------------


@pytest.mark.parametrize("order, rate, zeta", [(1, 2 * math.pi * 30, 0.0), (2, 2 * math.pi * 40, 0.7), (2, 30.0, 0.3)])
def test_transfer_trace_is_the_exact_steady_state(order, rate, zeta):
    """A sinusoidal command through delay and servo: displacement and acceleration are the
    frequency response's, to the propagator's exactness (the input is the command's cubic)."""
    dt, w, tau = 0.002, 2 * math.pi * 2.2, 0.004
    t = np.arange(6001) * dt
    cmd, slope = 0.02 * np.sin(w * t), 0.02 * w * np.cos(w * t)
    out = np.empty((2 * (len(t) - 1) + 1, 3))
    transfer_trace(cmd, slope, tau, 1.0, order, rate, zeta, servo_propagator(order, rate, zeta, dt / 2), dt, 2, out)
    response = Actuator(order, tau, 1.0, rate, zeta).response(2.2)
    settled = t > 25.0 / (zeta * rate if order == 2 else rate)  # the start-up transient below 1e-10
    exact = 0.02 * abs(response) * np.sin(w * t + np.angle(response))
    assert np.max(np.abs(out[::2, 0] - exact)[settled]) < 1e-9
    assert np.max(np.abs(out[::2, 2] + w * w * exact)[settled]) < 1e-5 * w * w * 0.02


def test_effective_delay_is_the_phase_lag_over_omega():
    w = 2 * math.pi * 2.2
    first = Actuator(1, 0.003, 1.0, 1 / 0.008)
    assert first.effective_delay(2.2) == pytest.approx(0.003 + math.atan(w * 0.008) / w, rel=1e-12)
    second = Actuator(2, 0.003, 1.0, 2 * math.pi * 10, 0.6)
    r = w / second.rate
    assert second.effective_delay(2.2) == pytest.approx(0.003 + math.atan2(2 * 0.6 * r, 1 - r * r) / w, rel=1e-12)
    assert second.amplitude(2.2) == pytest.approx(1 / math.hypot(1 - r * r, 2 * 0.6 * r), rel=1e-12)


def _steady_record(actuator: Actuator, rate_hz=500.0, seconds=8.0, noise=2e-5, seed=1):
    """Command of three tones and the LVDT reading of ``actuator``'s steady response to it, with noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * rate_hz) + 1) / rate_hz
    tones = ((0.015, 2.2), (0.008, 1.3), (0.004, 3.1))
    cmd = sum(a * np.sin(2 * math.pi * f * t) for a, f in tones)
    measured = sum(
        a * abs(h) * np.sin(2 * math.pi * f * t + np.angle(h)) for a, f in tones for h in [actuator.response(f)]
    )
    return t, cmd, measured + rng.normal(0, noise, len(t)) + 3e-5  # an LVDT offset too


@pytest.mark.parametrize(
    "truth, selected",
    [(Actuator(0, 0.012), "delay"), (Actuator(2, 0.004, 1.0, 2 * math.pi * 4.0, 0.4), "second_order")],
)
def test_identification_selects_by_held_out_error_and_finds_the_delay(truth, selected):
    """A pure delay is selected as such; a slow servo (4 Hz, zeta 0.4, tones at 1.3-3.1 Hz) needs its
    second order and is recovered. The effective delay at 2.2 Hz lies within 4 sigma of the truth."""
    t, cmd, measured = _steady_record(truth)
    ident = identify_transfer(t, cmd, measured, 2.2, Actuator(0, 0.0))
    assert ident.selected == selected
    delay, sigma = ident.effective_delay()
    assert abs(delay - truth.effective_delay(2.2)) < max(4 * sigma, 2e-5)
    assert abs(ident.best.offset - 3e-5) < 5e-6
    if selected == "second_order":
        fit = ident.best.actuator
        assert fit.rate == pytest.approx(truth.rate, rel=0.03) and fit.zeta == pytest.approx(truth.zeta, rel=0.05)


def test_a_slower_servo_than_described_is_named_servo_bandwidth():
    """Nominal: the 8 Hz servo the metadata describes, with the same transport delay; the rig's is 4 Hz."""
    truth = Actuator(2, 0.004, 1.0, 2 * math.pi * 4.0, 0.4)
    t, cmd, measured = _steady_record(truth)
    nominal = Actuator(2, 0.004, 1.0, 2 * math.pi * 8.0, 0.4)
    ident = identify_transfer(t, cmd, measured, 2.2, nominal)
    judged = judge_transfer(ident)
    assert judged["causes"] == ["servo_bandwidth"]
    assert judged["estimates"]["servo_bandwidth"][1] == pytest.approx(truth.rate, rel=0.03)
    # Described only by its delay (a pure-delay nominal), the same rig is an effective-delay error.
    plain = judge_transfer(identify_transfer(t, cmd, measured, 2.2, Actuator(0, nominal.effective_delay(2.2))))
    assert plain["causes"] == ["actuator_delay"]


@pytest.mark.parametrize("order, hz", [(2, 40.0), (1, 20.0)])
@pytest.mark.parametrize("effect", [{"servo_bandwidth": 0.35}, {"actuator_delay": 0.0135}])
def test_a_delay_and_a_slower_servo_the_record_cannot_separate_are_tied(order, hz, effect):
    """A described servo, slowed or delayed: at 2.2 Hz both lag alike, so the verdict is a tie with both estimates."""
    rig = Rig(servo_order=order, servo_hz=hz, describes_servo=True)
    _, js = verdict(servo_case(effect, rig=rig))
    assert js["cause"] == "actuator_delay" and js["tied_with"] == ["servo_bandwidth"], js["cause"]
    tied_rate = js["parts"]["transfer"]["tied_with"]["servo_bandwidth"]["rate"]
    nominal = 2 * math.pi * hz
    if "servo_bandwidth" in effect:  # the alternative explanation is the truth: its rate is the rig's
        assert tied_rate == pytest.approx(effect["servo_bandwidth"] * nominal, rel=0.05)
    else:  # a slower servo would explain the extra delay only at a rate well below the nominal's
        assert tied_rate < (1.0 - BANDWIDTH_TOLERANCE) * nominal


# -- the parts on independent servo rigs ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "rig, rate",
    [
        (Rig(hold=1), 500.0),
        (Rig(lead=0.008), 2000.0),
        (Rig(integrator=1, load_cell_tau=8e-4, calibration_error=4e-4), 500.0),
        (Rig(servo_order=1, servo_hz=20.0, describes_servo=True), 500.0),
        (Rig(servo_hz=300.0, delay=0.016), 2000.0),
    ],
    ids=["held-command", "predictor-2kHz", "central-difference+load-cell-lag", "first-order-servo", "near-ideal"],
)
def test_clean_rigs_with_other_conventions_are_named_none(rig, rate):
    """Controllers and rigs unlike the replay's (hold, predictor, integrator, load cell, servo): no cause."""
    _, js = verdict(servo_case(rig=rig, rate=rate, duration=10.0 if rate < 1000 else 5.0))
    assert js["cause"] == "none" and not js["unexplained"], js["cause"]


@pytest.mark.parametrize(
    "effects, part, rel",
    [
        ({"actuator_delay": 0.0135}, "transfer", 0.01),
        ({"servo_bandwidth": 0.35}, "transfer", None),
        ({"servo_gain": 0.92}, "transfer", 0.01),
        ({"oscillator_mass": 11.7}, "numerical", 0.01),
        ({"platform_mass": 1.3}, "physical", 0.03),
        ({"force_sensor_gain": 1.2}, "transfer", 0.03),
    ],
    ids=lambda v: "-".join(v) if isinstance(v, dict) else str(v),
)
def test_each_effect_is_named_in_its_own_part(effects, part, rel):
    """The actuator's effects never reach a numerical-model parameter, nor the specimen's a chain one."""
    case = servo_case(effects)
    _, js = verdict(case)
    cause = next(iter(effects))
    expected = "actuator_delay" if cause == "servo_bandwidth" else cause  # at 2.2 Hz a slower servo is a delay
    assert js["cause"] == expected and js["part_of"] == {expected: part}, js["cause"]
    assert not js["unexplained"]
    # No replayed part names anything else (the load cell's gain is fitted by the specimen's replay).
    assert {js["parts"][p]["cause"] for p in ("physical", "numerical")} <= {"none", expected}
    if rel is not None:
        key = {"actuator_delay": "tau", "servo_gain": "gain_servo", "oscillator_mass": "M", "platform_mass": "M2"}
        value = js["estimate"][key.get(cause, "gain_Fs")]
        assert value == pytest.approx(next(iter(effects.values())), rel=rel)


def test_a_wrong_model_and_a_wrong_actuator_are_told_apart_in_one_record():
    _, js = verdict(servo_case({"actuator_delay": 0.0135, "oscillator_stiffness": 2030.0}))
    assert js["cause"] == "actuator_delay+oscillator_stiffness"
    assert js["part_of"] == {"actuator_delay": "transfer", "oscillator_stiffness": "numerical"}
    assert js["estimate"]["K"] == pytest.approx(2030.0, rel=0.005)


@pytest.mark.parametrize("cause, value", [("oscillator_stiffness", 2030.0), ("spring_hardening", 1.5e6)])
def test_stiffness_and_hardening_are_told_apart_by_the_second_tone(cause, value):
    """K and k3 look alike at one amplitude; two tones at different amplitudes separate them."""
    _, js = verdict(servo_case({cause: value}))
    assert js["cause"] == cause and js["tied_with"] == []


# -- a hybrid test's own logs as records ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def site_log(tmp_path_factory):
    """A real `pendsweep site` session (servo actuator) driven by pendsweep's client over TCP."""
    from pendsweep.backends import make_backend

    log = tmp_path_factory.mktemp("site") / "site.parquet"
    site = ThreadSite({"actuator": "servo"}, timeout=10.0, log_path=log, fe=2.2)
    remote = make_backend("substructured", rig=f"tcp://127.0.0.1:{site.port}")
    run = remote.run_point(FIG9_PO, remote.initial_state(FIG9_PO, 0, 0, 0.1, 0), 6, 12)
    assert site.join() == 0 and run.status.value == "ok"
    return log


def _with_config(log: Path, out: Path, **changes) -> Path:
    """The log with its configuration changed (what the lab believes), the measurements as they are."""
    table = pq.read_table(log)
    meta = read_metadata(log)
    for section, values in changes.items():
        meta["config"][section].update(values)
    pq.write_table(table.replace_schema_metadata({METADATA_KEY: json.dumps(meta).encode()}), out)
    return out


def test_a_site_log_is_a_rig_record_and_its_clean_test_is_none(site_log):
    record = read_record(site_log)
    assert record.kind == "rig" and set(record.data.columns) == {"t", "y_cmd", "y", "theta", "Fs"}
    assert record.actuator["model"] == "second_order" and record.actuator["tau"] == pytest.approx(0.01)
    js = diagnose_records([record]).to_json()
    assert js["cause"] == "none" and not js["unexplained"]
    assert js["parts"]["numerical"]["cause"] == "not replayed" and "Fe" in js["parts"]["numerical"]["reason"]
    with pytest.raises(ConfigError, match="session 3 is not among them"):
        read_record(site_log, session=3)


def test_a_site_log_blames_the_specimen_or_the_actuator_as_its_metadata_is_wrong(site_log, tmp_path):
    """The lab's model of the platform is wrong (1.3 kg for 0.9): the specimen is blamed. Its actuator
    calibration is wrong (4 ms transport delay for 10): the actuator is, and nothing else."""
    heavy = _with_config(site_log, tmp_path / "heavy.parquet", params={"M2": 1.3, "M": 11.3})
    js = diagnose_records([read_record(heavy)]).to_json()
    assert js["cause"] == "platform_mass" and js["estimate"]["M2"] == pytest.approx(0.9, rel=0.03)
    late = _with_config(site_log, tmp_path / "late.parquet", rig={"transport_delay": 0.004})
    js = diagnose_records([read_record(late)]).to_json()
    assert js["cause"] == "actuator_delay" and js["part_of"] == {"actuator_delay": "transfer"}
    assert js["estimate"]["tau"] == pytest.approx(0.0174 + 0.0005, abs=0.0015)


def test_diagnose_command_on_a_site_log_writes_the_transfer_figure(site_log, tmp_path):
    report = tmp_path / "report"
    r = CliRunner().invoke(main, ["diagnose", str(site_log), "--report", str(report)])
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["cause"] == "none"
    assert (report / "transfer.png").stat().st_size > 10_000 and (report / "physical" / "report.md").exists()
    assert "Transfer system" in (report / "report.md").read_text()
    closed = CliRunner().invoke(main, ["diagnose", str(site_log), "--method", "closed-loop"])
    assert closed.exit_code == 2 and "part by part only" in closed.output


def test_a_substructured_trace_is_a_record_with_the_controllers_own_channels(tmp_path):
    out = tmp_path / "trace.parquet"
    r = CliRunner().invoke(main, ["trace", str(out), "--periods", "12", "--transient-periods", "6"])
    assert r.exit_code == 0, r.output
    record = read_record(out)
    assert record.kind == "substructured" and {"y_star", "F_fb", "y_cmd", "Fe"} <= set(record.data.columns)
    js = diagnose_records([record]).to_json()
    assert js["cause"] == "none"
    # The numerical model is compared on y* itself (no predictor lead to fit) and reproduces it.
    assert js["parts"]["numerical"]["error_before"] < 1e-3
    strided = tmp_path / "strided.parquet"
    CliRunner().invoke(main, ["trace", str(strided), "--periods", "2", "--transient-periods", "0", "--stride", "2"])
    with pytest.raises(ConfigError, match="--stride 1"):
        read_record(strided)


# -- units and sensors in a record's metadata ------------------------------------------------------------


def test_columns_in_other_units_are_converted_and_unknown_units_refused(tmp_path):
    record = generate(servo_case(duration=4.0))
    data = record.data.copy()
    csv = tmp_path / "lab.csv"
    lab = pd.DataFrame({"t": data.t, "theta": np.degrees(data.theta), "y": 1e3 * data.y, "Fe": data.Fe,
                        "y_cmd": 1e3 * data.y_cmd, "Fs": data.Fs / 1e3})  # fmt: skip
    lab.to_csv(csv, index=False, float_format="%.12g")
    meta = record.metadata()
    meta["columns"] = {"theta": {"unit": "deg", "sensor": "optical encoder"}, "y": {"unit": "mm"},
                       "y_cmd": {"unit": "mm"}, "Fs": {"unit": "kN", "sensor": "load cell"}}  # fmt: skip
    csv.with_suffix(".json").write_text(json.dumps(meta))
    read = read_record(csv)
    for c in ("theta", "y", "y_cmd", "Fs"):
        np.testing.assert_allclose(read.data[c], data[c], rtol=1e-10, atol=1e-15)
    assert read.sensors == {"theta": "optical encoder", "Fs": "load cell"}
    out = tmp_path / "si.parquet"
    write_record(read, out)
    assert read_metadata(out)["columns"]["Fs"] == {"unit": "N", "description": "interface force (load cell)",
                                                   "sensor": "load cell"}  # fmt: skip
    meta["columns"]["y"] = {"unit": "furlong"}
    csv.with_suffix(".json").write_text(json.dumps(meta))
    r = CliRunner().invoke(main, ["diagnose", str(csv)])
    assert r.exit_code == 2 and "column 'y' in unit 'furlong'; accepted: m, mm" in r.output
    assert len(r.output.strip().splitlines()) == 1
    # Undeclared units that the scales give away: displacements in mm (both), the load cell in kN.
    for undeclared, message in ((("y", "y_cmd"), "beyond any actuator stroke"), (("Fs",), "the load cell Fs reads")):
        meta["columns"] = {c: spec for c, spec in meta["columns"].items() if c not in (*undeclared, "y")}
        meta["columns"].update({c: {"unit": {"y": "mm", "y_cmd": "mm", "Fs": "kN"}[c]} for c in ("y", "y_cmd", "Fs")
                                if c not in undeclared})  # fmt: skip
        csv.with_suffix(".json").write_text(json.dumps(meta))
        r = CliRunner().invoke(main, ["diagnose", str(csv)])
        assert r.exit_code == 2 and message in r.output, r.output
        assert len(r.output.strip().splitlines()) == 1


def test_an_actuator_table_in_the_metadata_is_checked(tmp_path):
    record = generate(servo_case(duration=4.0))
    record = Record(record.data, record.kind, record.params, record.tau, record.forcing, "lab",
                    {"model": "second_order", "tau": 0.003, "rate": 250.0, "zeta": 0.7})  # fmt: skip
    out = tmp_path / "rec.parquet"
    write_record(record, out)
    assert read_record(out).actuator == {"model": "second_order", "tau": 0.003, "rate": 250.0, "zeta": 0.7}
    table = pq.read_table(out)
    meta = read_metadata(out)
    meta["actuator"] = {"model": "third_order"}
    pq.write_table(table.replace_schema_metadata({METADATA_KEY: json.dumps(meta).encode()}), out)
    with pytest.raises(ConfigError, match="actuator model 'third_order' is unknown"):
        read_record(out)


# -- the DAQ's sampling declared in the metadata (issue 34) ------------------------------------------------


@pytest.mark.parametrize("ramped", [False, True], ids=["held", "ramped"])
def test_sampled_transfer_trace_is_the_exact_response_to_a_staircase_or_broken_line(ramped):
    """A command step held (or ramped over one tick) into a second-order servo behind a delay that is
    no whole number of rows: the exact step (ramp) response, at every row."""
    from pendsweep.kernels._measured import sampled_transfer_trace

    dt, per_sample, tau, ws, zeta = 0.002, 4, 0.0033, 2 * math.pi * 30, 0.7
    cmd = np.where(np.arange(201) >= 20, 1e-3, 0.0)
    h = dt / per_sample
    split = math.fmod(tau, h)
    first, second = (servo_propagator(2, ws, zeta, d) for d in (split, h - split))
    out = np.empty((200 * per_sample + 1, 3))
    sampled_transfer_trace(cmd, tau, 1.0, 2, ws, zeta, first, second, split, ramped, dt, per_sample, out)
    wd = ws * math.sqrt(1 - zeta * zeta)

    def step(s):  # unit step response from rest, s >= 0
        s = np.maximum(s, 0.0)
        return 1 - np.exp(-zeta * ws * s) * (np.cos(wd * s) + zeta / math.sqrt(1 - zeta * zeta) * np.sin(wd * s))

    t = np.arange(len(out)) * h
    start = (20 - (1 if ramped else 0)) * dt + tau  # the ramp from sample 19 to 20, or the switch at 20
    exact = np.array([_ramp_response(s, ws, zeta, dt) for s in t - start]) if ramped else step(t - start)
    assert np.max(np.abs(out[:, 0] / 1e-3 - exact)) < 1e-9


def _ramp_response(s, ws, zeta, dt):
    """Response of ``x'' = ws^2 (u - x) - 2 zeta ws x'`` to ``u`` rising linearly from 0 to 1 over ``dt``
    from ``s = 0`` (quadrature of the step response: the ramp's derivative is a box of height 1/dt)."""
    from scipy.integrate import quad

    wd = ws * math.sqrt(1 - zeta * zeta)

    def step(r):
        if r <= 0:
            return 0.0
        return 1 - math.exp(-zeta * ws * r) * (math.cos(wd * r) + zeta / math.sqrt(1 - zeta**2) * math.sin(wd * r))

    if s <= 0:
        return 0.0
    return quad(lambda v: step(s - v), 0.0, min(s, dt), epsabs=1e-13, epsrel=1e-12)[0] / dt


def test_a_held_command_into_a_point_sampled_load_cell_is_modelled_when_the_record_declares_it():
    """A load cell sampled at the tick and a command held over it (a staircase into a 30 Hz servo):
    declared in the metadata (``daq``), the specimen's replay samples Eq. (4) at the tick under the
    staircase's motion and the clean record is named ``none``; undeclared, the replay reads the tick
    mean of a smooth command's motion and blames the specimen (the known limit)."""
    rig = dict(servo_hz=30.0, delay=0.0033, hold=1, point_load_cell=True, describes_servo=True)
    declared = generate(servo_case(rig=Rig(**rig, declares_daq=True), duration=8.0))
    assert declared.daq == {"load_cell": "point", "command": "held"}
    _, js = verdict(servo_case(rig=Rig(**rig, declares_daq=True), duration=8.0))
    assert js["cause"] == "none" and not js["unexplained"], js["cause"]
    _, plain = verdict(servo_case(rig=Rig(**rig), duration=8.0))
    assert plain["cause"] != "none" or plain["unexplained"], plain["cause"]


def test_the_daq_key_is_read_written_and_checked(tmp_path):
    record = generate(servo_case(duration=4.0))
    daq = {"load_cell": "point", "command": "ramped"}
    record = Record(record.data, record.kind, record.params, record.tau, record.forcing, "lab", daq=daq)
    assert record.sampling("load_cell") == "point" and Record(record.data, "rig").sampling("command") == "smooth"
    csv = tmp_path / "rec.csv"
    write_record(record, csv)
    assert read_record(csv).daq == daq
    meta = json.loads(csv.with_suffix(".json").read_text())
    for bad, message in [
        ({"load_cell": "averaged"}, "daq.load_cell = 'averaged'; accepted: tick_mean, point"),
        ({"command": "linear"}, "daq.command = 'linear'; accepted: smooth, ramped, held"),
        ({"clock": "gps"}, "unknown daq key 'clock'; accepted: load_cell, command"),
        ("point", "metadata 'daq' must be a JSON object"),
    ]:
        csv.with_suffix(".json").write_text(json.dumps(dict(meta, daq=bad)))
        r = CliRunner().invoke(main, ["diagnose", str(csv)])
        assert r.exit_code == 2 and message in r.output, r.output
        assert len(r.output.strip().splitlines()) == 1
