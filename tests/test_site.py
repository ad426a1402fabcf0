"""The experimental site: protocol, rig semantics, a hostile network, the client direction, the command.

Everything here goes through real sockets on loopback. OpenSees's own client
is in ``test_opensees.py``.
"""

from __future__ import annotations

import json
import math
import re
import socket
import struct
import subprocess
import sys
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

from pendsweep import FIG9_PO, make_backend
from pendsweep.errors import ConfigError
from pendsweep.hybrid import ProtocolError, opensees_setup, parse_setup
from pendsweep.hybrid.access import LOOPBACK_NETWORKS, admits, loopback_only_warning, parse_allow
from pendsweep.hybrid.rig import rig_from_options
from pendsweep.model.params import ModelParams
from site_helpers import OPENSEES_SETUP, RawClient, SiteProcess, ThreadSite

DT = 1e-3


# -- the set-up message -------------------------------------------------------------------
def test_opensees_setup_is_accepted_and_round_trips():
    setup = parse_setup(struct.pack("<11i", *OPENSEES_SETUP))
    assert setup.ctrl == (1, 1, 1, 0, 1) and setup.daq == (0, 0, 0, 1, 0) and setup.data_size == 256
    assert opensees_setup() == setup  # what GenericClient::setupConnection sends for one dof
    assert parse_setup(setup.pack()) == setup


@pytest.mark.parametrize(
    ("sizes", "reason"),
    [
        ((2, 1, 1, 0, 1, 0, 0, 0, 1, 0, 256), "sizeCtrl.disp = 2"),
        ((1, 1, 1, 1, 1, 0, 0, 0, 1, 0, 256), "sizeCtrl.force = 1"),
        ((1, 3, 1, 0, 1, 0, 0, 0, 1, 0, 256), "sizeCtrl.vel = 3"),
        ((1, 1, 1, 0, 1, 0, 0, 0, 9, 0, 256), "sizeDaq.force = 9"),
        ((1, 1, 1, 0, 1, -1, 0, 0, 1, 0, 256), "sizeDaq.disp = -1"),
        ((1, 1, 1, 0, 1, 0, 0, 0, 1, 0, 2**30), "dataSize = 1073741824"),  # 8 GiB frames
        ((1, 1, 1, 0, 1, 0, 0, 0, 1, 0, 3), "dataSize = 3"),  # smaller than a trial
        ((1, 1, 1, 0, 1, 0, 0, 0, 1, 0, -5), "dataSize = -5"),
    ],
)
def test_bad_setup_is_refused_with_the_field_named(sizes, reason):
    with pytest.raises(ProtocolError, match=reason.replace("(", r"\(")):
        parse_setup(struct.pack("<11i", *sizes))


# -- the rig's semantics --------------------------------------------------------------------
def _rig(**options):
    return rig_from_options({k: str(v) for k, v in options.items()}, FIG9_PO)[0]


def test_repeated_trials_never_advance_the_rig_and_commit_keeps_the_last():
    rig = _rig()
    first = rig.trial(1e-4, 0.1, 0.0, DT).copy()
    for _ in range(5):
        again = rig.trial(1e-4, 0.1, 0.0, DT)
    np.testing.assert_array_equal(first, again)  # the same trial from the same committed state
    other = rig.trial(2e-4, 0.2, 0.0, DT).copy()
    assert not np.array_equal(first, other)
    assert rig.committed_time == 0.0
    assert rig.commit() and rig.committed_time == DT
    np.testing.assert_array_equal(rig.committed_readings, other)  # the last trial is what was kept


def test_a_trial_at_the_committed_time_holds_the_rig():
    rig = _rig()
    held = rig.trial(0.0, 0.0, 0.0, 0.0)  # OpenSees sends one at t = 0
    np.testing.assert_array_equal(held, rig.committed_readings)
    assert not rig.commit() and rig.committed_step == 0


def test_rig_trial_is_the_in_process_rig_tick():
    """Driven by the in-process loop's commands, the site's rig reproduces its encoder angle exactly."""
    opts = dict(actuator="servo", force_noise=0, lvdt_noise=0, harmonic3=0, harmonic5=0, harmonic7=0)
    backend = make_backend("substructured", **opts)
    params = FIG9_PO
    trace = backend.trace(params, backend.initial_state(params, 0, 0, 0.1, 0), 3)
    rig = _rig(**opts)
    dt = backend.step(params)
    theta = []
    for k in range(1, len(trace)):
        # command c_k and its slope: the trace's command column holds the command of tick k
        rig.trial(trace["command"][k], (trace["command"][k] - trace["command"][k - 1]) / dt, 0.0, k * dt)
        rig.commit()
        theta.append(rig.committed_readings[2])
    # the slope differs from the predictor's own, so x differs slightly; the angle follows to 1e-3 rad
    assert np.max(np.abs(np.array(theta) - trace["theta_true"][1:].to_numpy())) < 2e-3


@pytest.mark.parametrize(
    ("trial", "reason"),
    [
        ((float("nan"), 0.0, 0.0, DT), "trial displacement nan is not finite"),
        ((0.0, float("inf"), 0.0, DT), "trial velocity inf is not finite"),
        ((0.0, 0.0, 0.0, float("nan")), "trial time nan is not finite"),
        ((0.08, 0.0, 0.0, DT), "beyond the rig's stroke"),
        ((0.0, 1.5, 0.0, DT), "beyond the rig's limit"),
        ((0.0, 0.0, 0.0, -DT), "before the committed time"),
    ],
)
def test_bad_trials_are_refused_and_the_rig_held(trial, reason):
    rig = _rig()
    before = rig.committed.copy()
    with pytest.raises(ProtocolError, match=reason):
        rig.trial(*trial)
    np.testing.assert_array_equal(rig.committed, before)


def test_the_step_is_fixed_by_the_first_trial():
    rig = _rig()
    rig.trial(0.0, 0.0, 0.0, DT)
    rig.commit()
    with pytest.raises(ProtocolError, match="differs from the constant step"):
        rig.trial(0.0, 0.0, 0.0, 3 * DT)  # a second step twice the first: not AlphaOS's alpha dt, then dt


def test_force_limit_trips_on_the_load_cell():
    rig = _rig(force_limit=0.5)
    with pytest.raises(ProtocolError, match="load cell reads .* beyond its range"):
        for k in range(1, 200):  # a 1 m/s^2 ramp: (M2 + m) a = 1.17 N
            t = k * DT
            rig.trial(0.5 * t * t, t, 1.0, t)
            rig.commit()


def test_reported_mass_takes_the_platform_inertia_out_of_the_force():
    """With the pendulum at rest, the force is C2 x' + (M2 + m) x''; reported mass leaves C2 x'.

    The load cell reads the mean over the step (an integrating ADC), so at
    constant acceleration x' is taken at the step's middle.
    """
    common = dict(force_noise=0, lvdt_noise=0)
    params = ModelParams.from_mapping({})
    for report in (True, False):
        rig = rig_from_options({k: str(v) for k, v in common.items()} | {"report_mass": str(report)}, params, 0.0)[0]
        a = 2.0
        for k in range(1, 101):
            t = k * DT
            rig.trial(0.5 * a * t * t, a * t, a, t)
            rig.commit()
        v_mid = a * (100 - 0.5) * DT
        expected = params.C2 * v_mid + (0.0 if report else (params.M2 + params.m) * a)
        assert rig.force() == pytest.approx(expected, rel=1e-9)
        assert rig.mass() == (params.M2 + params.m if report else 0.0)


def test_site_options_are_the_rigs_only():
    with pytest.raises(ConfigError, match="predictor_order: not an option of the rig"):
        rig_from_options({"predictor_order": "1"}, FIG9_PO)
    with pytest.raises(ConfigError, match="report_mass"):
        rig_from_options({"report_mass": "maybe"}, FIG9_PO)
    with pytest.raises(ConfigError, match="velocity_limit=-1"):
        rig_from_options({"velocity_limit": "-1"}, FIG9_PO)


# -- a hostile network: every case ends in one line, a held rig and no hang ---------------------
def _fault(site: ThreadSite, expect: str) -> None:
    assert site.join() == 1
    assert expect in site.reason, site.reason
    assert "\n" not in site.reason


def _ok_steps(client: RawClient, n: int) -> None:
    for k in range(n):
        client.step(1e-5 * k, 1e-2, (k + 1) * DT)


@pytest.mark.parametrize(
    ("script", "expect"),
    [
        (lambda c: c.send(b"\x01\x00\x00"), "mid-set-up (3 of 44 bytes)"),
        (lambda c: c.setup((1, 1, 1, 0, 1, 0, 0, 0, 1, 0, 2**28)), "dataSize = 268435456"),
        (lambda c: (c.setup(), c.send(b"\x00" * 100)), "mid-frame (100 of 2048 bytes)"),
        (lambda c: (c.setup(), c.frame(42)), "unknown action 42.0"),
        (lambda c: (c.setup(), c.frame(float("nan"))), "unknown action nan"),
        (lambda c: (c.setup(), c.frame(3.5)), "unknown action 3.5"),
        (lambda c: (c.setup(), c.frame(3, float("nan"), 0, 0, DT)), "trial displacement nan"),
        (lambda c: (c.setup(), c.frame(3, 0.0, 0, 0, float("inf"))), "trial time inf"),
        (lambda c: (c.setup(), _ok_steps(c, 3), c.frame(3, 0.2, 0, 0, 4 * DT)), "beyond the rig's stroke"),
        (lambda c: (c.setup(), _ok_steps(c, 3), c.frame(3, 0.0, 5.0, 0, 4 * DT)), "beyond the rig's limit"),
        (lambda c: (c.setup(), _ok_steps(c, 3), c.frame(3, 0.0, 0, 0, DT)), "before the committed time"),
        (lambda c: (c.setup(), _ok_steps(c, 2), c.frame(3, 0.0, 0.0, 0.0, 3 * DT)), "client closed the connection"),
        (lambda c: (c.setup(), c.frame(3, 0.0, 0, 0, 0.2)), "trial step 0.2 s outside the rig's accepted"),
        (lambda c: (c.setup(), c.frame(3, 0.0, 0, 0, 1.5e-9)), "trial step 1.5e-09 s outside the rig's accepted"),
        (lambda c: None, "client silent: set-up message not complete within 1 s (0 of 44 bytes)"),
        (lambda c: c.setup(), "client silent: frame not complete within 1 s"),
    ],
    ids=[
        "truncated-setup", "gigabyte-frames", "truncated-frame", "unknown-action", "nan-action", "fractional-action",
        "nan-trial", "inf-time", "stroke", "velocity", "time-backwards", "vanishes-mid-step", "huge-step", "tiny-step",
        "silent", "silent-after-setup",
    ],
)  # fmt: skip
def test_hostile_clients_end_in_one_line_and_a_held_rig(script, expect):
    site = ThreadSite(timeout=1.0)
    client = RawClient(site.port)
    try:
        script(client)
        if "silent" not in expect:
            time.sleep(0.05)
            client.close()
        _fault(site, expect)
    finally:
        client.close()
    committed = site.log.n_rows
    assert site.rig.committed_step == committed  # the faulty step never committed: the rig held


def test_the_velocity_limit_holds_without_a_declared_velocity():
    """A client that sends no velocity cannot drive the platform past the limit: the rig's own speed counts."""
    site = ThreadSite(timeout=1.0)
    client = RawClient(site.port)
    client.setup((1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 256))  # displacement and time only
    client.frame(3, 1.5e-3, DT)  # 1.5 mm in a millisecond, with no velocity declared
    _fault(site, "platform moved at 1.5 m/s, beyond the rig's limit")
    client.close()


def test_alphaos_short_first_step_is_accepted():
    """OpenSees's AlphaOS with alpha < 1 sends its trials at alpha dt, then dt apart."""
    rig = _rig(actuator="servo")
    alpha = 0.9
    for k in range(5):
        rig.trial(1e-5 * k, 0.0, 0.0, (k + alpha) * DT)
        rig.commit()
    assert rig.dt == pytest.approx(DT) and rig.committed_step == 5
    with pytest.raises(ProtocolError, match="differs from the constant step"):
        rig.trial(0.0, 0.0, 0.0, (5 + alpha) * DT + 0.5 * DT)


def test_the_client_refuses_garbage_from_a_site():
    """A site is as hostile as a client: a NaN or absurd reading stops the run with one line (status 1)."""
    import threading

    from pendsweep.errors import RunFailure

    for bad in (float("nan"), 1e300):
        server = socket.create_server(("127.0.0.1", 0))
        port = server.getsockname()[1]

        def fake_site(value=bad, server=server):
            conn, _ = server.accept()
            conn.recv(44)
            frame = conn.recv(8 * 16)
            reply = np.zeros(16)
            reply[1] = value  # the encoder angle
            if frame:
                conn.sendall(reply.tobytes())
            time.sleep(0.5)
            conn.close()

        thread = threading.Thread(target=fake_site, daemon=True)
        thread.start()
        remote = make_backend("substructured", rig=f"tcp://127.0.0.1:{port}")
        with pytest.raises(RunFailure, match="not finite or beyond"):
            remote.run_point(FIG9_PO, remote.initial_state(FIG9_PO, 0, 0, 0.1, 0), 1, 1)
        thread.join(5)
        server.close()


def test_an_oversized_frame_is_an_unknown_action_not_a_misread():
    site = ThreadSite(timeout=1.0)
    client = RawClient(site.port)
    client.setup((1, 1, 1, 0, 1, 0, 0, 0, 1, 0, 8))
    # 16 float64 where 8 were agreed: the stream has no frame marks, so the tail is read as the next
    # frame, whose action 7e300 is unknown (a tail shorter than a frame would time out instead)
    too_long = np.zeros(16)
    too_long[0], too_long[8] = 5, 7e300
    client.send(too_long.astype("<f8").tobytes())
    _fault(site, "unknown action 7e+300")
    client.close()


def test_a_second_client_is_refused_while_the_first_is_served(capfd):
    site = ThreadSite(timeout=2.0)
    first = RawClient(site.port)
    first.setup()
    _ok_steps(first, 5)
    second = socket.create_connection(("127.0.0.1", site.port), timeout=2)
    assert second.recv(16) == b""  # closed by the site without a byte
    _ok_steps_from = 5
    for k in range(_ok_steps_from, _ok_steps_from + 5):
        first.step(1e-5 * k, 1e-2, (k + 1) * DT)
    first.frame(99)
    assert site.join() == 0
    assert site.log.n_rows == 10
    assert "refused a second client" in capfd.readouterr().err
    first.close()
    second.close()


# -- who may drive the rig: the allow-list ------------------------------------------------------------
def _site_metadata(path) -> dict:
    return json.loads(pq.read_table(path).schema.metadata[b"pendsweep"])


def test_the_default_allow_list_admits_any_loopback_address():
    site = ThreadSite(timeout=2.0)
    client = RawClient(site.port, source="127.0.0.2")
    client.setup()
    _ok_steps(client, 5)
    client.frame(99)
    assert site.join() == 0
    assert site.server.sessions[-1].peer.startswith("127.0.0.2:") and site.log.n_rows == 5
    assert site.log.refused_total == 0
    client.close()


@pytest.mark.parametrize(
    ("allow", "outsider", "member"),
    [(("127.0.0.1",), "127.0.0.2", "127.0.0.1"), (("127.0.0.0/30",), "127.0.0.9", "127.0.0.2")],
    ids=["address", "cidr"],
)
def test_a_client_outside_the_allow_list_is_closed_before_set_up(allow, outsider, member, tmp_path, capfd):
    """Refused before and during the one session of a --once site: it neither ends the site nor is its client.

    Admitted, the first outsider would have been the session (the site waits 1 s
    for its set-up, then ends with a fault): the member's clean session proves it was not.
    """
    site = ThreadSite(timeout=1.0, allow=allow, log_path=tmp_path / "log.parquet")
    early = RawClient(site.port, source=outsider)
    assert early.sock.recv(16) == b""  # closed by the site without a byte, and without waiting for a set-up
    client = RawClient(site.port, source=member)
    client.setup()
    _ok_steps(client, 5)
    late = RawClient(site.port, source=outsider)
    assert late.sock.recv(16) == b""
    for k in range(5, 10):
        client.step(1e-5 * k, 1e-2, (k + 1) * DT)  # the session in progress goes on
    client.frame(99)
    assert site.join() == 0
    assert len(site.server.sessions) == 1 and site.log.n_rows == 10
    refused = _site_metadata(tmp_path / "log.parquet")["refused"]
    assert [r["peer"].rsplit(":", 1)[0] for r in refused] == [outsider, outsider]
    assert capfd.readouterr().err.count(f"pendsweep site: refused client {outsider}:") == 2
    for each in (early, client, late):
        each.close()


def test_the_allow_list_reads_ipv6_and_ipv4_mapped_addresses():
    assert admits(LOOPBACK_NETWORKS, "::1") and admits(LOOPBACK_NETWORKS, "::ffff:127.0.0.2")
    assert not admits(LOOPBACK_NETWORKS, "::ffff:192.168.10.7") and not admits(LOOPBACK_NETWORKS, "192.168.10.7")
    lab = parse_allow(["fd00::/64, 192.168.10.0/24", "10.1.2.3"])
    assert [str(n) for n in lab] == ["fd00::/64", "192.168.10.0/24", "10.1.2.3/32"]
    assert admits(lab, "fd00::5") and admits(lab, "::ffff:192.168.10.7") and admits(lab, "10.1.2.3")
    assert not admits(lab, "10.1.2.4") and not admits(lab, "127.0.0.1")  # given networks replace loopback


@pytest.mark.parametrize("value", ["10.0.0.0/33", "127.0.0.1,", "fd00::/129", "localhost"])
def test_an_allow_value_that_is_no_address_or_network_is_named(value):
    bad = value.split(",")[-1]
    with pytest.raises(ConfigError, match=f"--allow '{bad}' is not an IPv4 or IPv6 address or CIDR network"):
        parse_allow([value])


def test_random_bytes_never_hang_the_site():
    rng = np.random.default_rng(21)
    for trial in range(25):
        site = ThreadSite(timeout=0.5)
        client = RawClient(site.port)
        n = int(rng.integers(1, 5000))
        payload = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        if trial % 2:  # a valid set-up first, so the random bytes land in frames
            client.setup((1, 1, 1, 0, 1, 0, 0, 0, 1, 0, 16))
        client.send(payload)
        started = time.monotonic()
        status = site.join(limit=10.0)
        assert status == 1 and site.reason
        assert time.monotonic() - started < 5.0
        client.close()


def test_die_ends_cleanly_and_the_log_holds_every_committed_step(tmp_path):
    site = ThreadSite(log_path=tmp_path / "log.parquet", timeout=2.0)
    client = RawClient(site.port)
    client.setup()
    client.frame(15)
    assert client.reply()[0] == pytest.approx(FIG9_PO.M2 + FIG9_PO.m)  # getMass: the carried mass
    forces = [client.step(1e-4 * k, 0.1, (k + 1) * DT) for k in range(50)]
    client.frame(99)
    assert site.join() == 0
    table = pq.read_table(tmp_path / "log.parquet")
    assert table.num_rows == 50
    np.testing.assert_allclose(table["t"].to_numpy(), DT * np.arange(1, 51), rtol=1e-12)
    np.testing.assert_array_equal(table["force"].to_numpy(), forces)
    meta = site.log.sessions[-1]
    assert meta["ended"] == "die" and meta["steps"] == 50


# -- the other direction: pendsweep's controller against a site ------------------------------------
NOISELESS = ("-B", "force_noise=0", "-B", "lvdt_noise=0")


@pytest.mark.parametrize("actuator", ["servo", "ideal"])
def test_client_against_site_equals_the_in_process_backend(actuator):
    """Same arithmetic on both sides of the socket: the records are identical, not just close.

    The noise is off because the two draw it in different chunks (the site
    does not know how long the controller's run will be); quantisation and
    every deterministic part of the rig are on.
    """
    opts = dict(actuator=actuator, force_noise=0, lvdt_noise=0, harmonic3=0, harmonic5=0, harmonic7=0)
    local = make_backend("substructured", **opts)
    site = SiteProcess("--once", "--set", "fe=2.2", "-B", f"actuator={actuator}", *NOISELESS)
    remote = make_backend("substructured", actuator=actuator, rig=f"tcp://127.0.0.1:{site.port}")
    a = local.run_point(FIG9_PO, local.initial_state(FIG9_PO, 0, 0, 0.1, 0), 20, 10)
    b = remote.run_point(FIG9_PO, remote.initial_state(FIG9_PO, 0, 0, 0.1, 0), 20, 10)
    status, err = site.finish()
    assert status == 0, err
    assert a.status == b.status and a.periods_done == b.periods_done == 30
    np.testing.assert_array_equal(a.records, b.records)
    assert b.round_trip is not None and np.all(b.round_trip > 0)


def test_a_noisy_remote_rig_runs_like_the_in_process_one():
    """With the site's default sensor noise the loop stays stable and the orbit is the in-process one.

    The remote controller sees only the LVDT: its instability monitor reads the
    daq acceleration, since the LVDT's 20 um noise differenced twice at 1 kHz
    reads as 20 m/s^2 and would trip it within two periods.
    """
    site = SiteProcess("--once", "--set", "fe=2.2", "-B", "actuator=servo")
    remote = make_backend("substructured", rig=f"tcp://127.0.0.1:{site.port}")
    run = remote.run_point(FIG9_PO, remote.initial_state(FIG9_PO, 0, 0, 0.1, 0), 60, 20)
    assert site.finish()[0] == 0
    assert run.status.value == "ok" and run.periods_done == 80
    local = make_backend("substructured", harmonic3=0, harmonic5=0, harmonic7=0)
    ref = local.run_point(FIG9_PO, local.initial_state(FIG9_PO, 0, 0, 0.1, 0), 60, 20)
    assert abs(run.records[:, 1].max() / ref.records[:, 1].max() - 1) < 0.01


def test_a_sweep_runs_through_a_remote_rig(tmp_path):
    site = SiteProcess("--set", "fe=2.2", *NOISELESS)
    try:
        out = tmp_path / "remote.parquet"
        cmd = [sys.executable, "-m", "pendsweep.cli", "alpha", "--from", "4", "--to", "5", "--step", "1", "--fe",
               "2.2", "--mode", "fresh", "--transient-periods", "10", "--record-periods", "5", "--no-progress",
               "--backend", "substructured", "-B", f"rig=tcp://127.0.0.1:{site.port}", "-o", str(out)]  # fmt: skip
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
    finally:
        status, err = site.stop()
    assert status == 0, err
    assert err.count("left after 6825 steps") == 2, err  # one session per point, 15 periods of 455 steps
    rows = pq.read_table(out)
    assert rows.num_rows == 10
    assert {"round_trip_p50", "round_trip_p99", "round_trip_max"} <= set(rows.column_names)
    assert np.all(rows["round_trip_p50"].to_numpy() > 0)


@pytest.mark.parametrize(
    ("args", "expect"),
    [
        (["--mode", "multistart"], "not multistart"),
        (["--mode", "fresh", "-B", "force_noise=0.5"], "force_noise describes the rig"),
        (["--mode", "fresh", "-B", "harmonic3=0.1"], "harmonic3 describes the rig"),  # even at its default
        (["--mode", "fresh", "-B", "rig=udp://x:1"], "give tcp://HOST:PORT"),
    ],
)
def test_remote_rig_refusals_exit_2(args, expect, tmp_path):
    cmd = [sys.executable, "-m", "pendsweep.cli", "alpha", "--from", "4", "--to", "5", "--backend", "substructured",
           "-B", "rig=tcp://127.0.0.1:9", "-o", str(tmp_path / "x.parquet"), *args]  # fmt: skip
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert expect in done.stderr and len(done.stderr.strip().splitlines()) == 1


# -- the command -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("args", "expect"),
    [
        (["--port", "70000"], "70000"),
        (["--timeout", "nan"], "not finite"),
        (["--timeout", "0"], "outside the accepted range"),
        (["-B", "predictor_order=1"], "not an option of the rig"),
        (["-B", "actuator=magic"], "actuator = 'magic'"),
        (["--set", "m=-1"], "m"),
        (["-o", "log.csv"], ".parquet"),
        (["--theta0", "inf"], "not finite"),
        (["--allow", "127.0.0.1,lab-pc"], "--allow 'lab-pc' is not an IPv4 or IPv6 address or CIDR network"),
        (["--allow", "10.0.0.1/24"], "give the network 10.0.0.0/24 or the address 10.0.0.1"),
    ],
)
def test_site_bad_input_exits_2_with_one_line(args, expect, tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "pendsweep.cli", "site", *args], capture_output=True, text=True, timeout=120,
        cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert expect in done.stderr and len(done.stderr.strip().splitlines()) == 1


def test_site_command_once_logs_and_summarises(tmp_path):
    log = tmp_path / "log.parquet"
    site = SiteProcess("--once", "-o", str(log), "--theta0", "0.2")
    client = RawClient(site.port)
    client.setup()
    for k in range(100):
        client.step(0.0, 0.0, (k + 1) * DT)
    client.frame(99)
    status, err = site.finish()
    client.close()
    assert status == 0, err
    assert "left after 100 steps" in err and "service time p50" in err
    table = pq.read_table(log)
    assert table.num_rows == 100
    assert abs(table["theta_true"].to_numpy()[0] - 0.2) < 1e-3  # the site's own initial angle
    meta = __import__("json").loads(table.schema.metadata[b"pendsweep"])
    assert meta["kind"] == "site-log" and meta["config"]["initial"]["theta0"] == 0.2
    assert meta["config"]["rig"]["actuator"] == "ideal" and meta["sessions"][0]["ended"] == "die"


def test_a_site_beyond_loopback_without_allow_warns_once_and_serves_loopback(tmp_path):
    assert loopback_only_warning("127.0.0.1", allow_given=False) is None
    assert loopback_only_warning("::ffff:127.0.0.1", allow_given=False) is None
    assert loopback_only_warning("0.0.0.0", allow_given=True) is None
    assert "only loopback clients" in loopback_only_warning("::", allow_given=False)
    log = tmp_path / "log.parquet"
    site = SiteProcess("--once", "--host", "0.0.0.0", "-o", str(log))  # a free port, only ever reached from loopback
    client = RawClient(site.port, source="127.0.0.2")
    client.setup()
    client.frame(99)
    status, err = site.finish()
    client.close()
    assert status == 0, err
    assert err.count("only loopback clients (127.0.0.0/8, ::1) will be accepted; give --allow") == 1, err
    assert _site_metadata(log)["config"]["allow"] == ["127.0.0.0/8", "::1/128"]


def test_site_command_allow_refuses_other_clients_and_logs_them(tmp_path):
    log = tmp_path / "log.parquet"
    site = SiteProcess("--once", "--allow", "127.0.0.1, ::1", "-o", str(log))
    outsider = RawClient(site.port, source="127.0.0.2")
    assert outsider.sock.recv(16) == b""
    client = RawClient(site.port)
    client.setup()
    client.step(0.0, 0.0, DT)
    client.frame(99)
    status, err = site.finish()
    outsider.close()
    client.close()
    assert status == 0, err
    assert "pendsweep site: refused client 127.0.0.2:" in err and "warning" not in err
    meta = _site_metadata(log)
    assert meta["config"]["allow"] == ["127.0.0.1/32", "::1/128"]
    assert meta["refused_total"] == 1 and meta["sessions"][0]["ended"] == "die"


def test_site_command_fault_exits_1_and_keeps_the_log(tmp_path):
    log = tmp_path / "log.parquet"
    site = SiteProcess("--once", "-o", str(log))
    client = RawClient(site.port)
    client.setup()
    for k in range(10):
        client.step(0.0, 0.0, (k + 1) * DT)
    client.frame(3, 1.0, 0.0, 0.0, 11 * DT)  # a metre: beyond the stroke
    status, err = site.finish()
    client.close()
    assert status == 1
    assert "stopped: trial displacement 1 m beyond the rig's stroke +-0.075 m" in err
    assert "Traceback" not in err
    assert pq.read_table(log).num_rows == 10


def test_site_stops_on_sigterm_with_its_log(tmp_path):
    log = tmp_path / "log.parquet"
    site = SiteProcess("-o", str(log))
    client = RawClient(site.port)
    client.setup()
    for k in range(20):
        client.step(0.0, 0.0, (k + 1) * DT)
    client.frame(99)
    client.close()
    time.sleep(0.3)
    status, err = site.stop()
    assert status == 0 and "stopped by a signal" in err
    assert pq.read_table(log).num_rows == 20


def test_a_signal_mid_session_is_recorded_and_exits_1(tmp_path):
    log = tmp_path / "log.parquet"
    site = SiteProcess("--once", "-o", str(log))
    client = RawClient(site.port)
    client.setup()
    for k in range(30):
        client.step(0.0, 0.0, (k + 1) * DT)
    client.frame(10)
    client.reply()  # the site has read every frame before: the 30th commit is in
    status, err = site.stop()
    client.close()
    assert status == 1 and "stopped by a signal mid-session" in err
    table = pq.read_table(log)
    meta = __import__("json").loads(table.schema.metadata[b"pendsweep"])
    assert table.num_rows == 30 and meta["sessions"][0]["reason"] == "the site was stopped by a signal"


def test_realtime_paces_to_the_wall_clock():
    site = ThreadSite(timeout=2.0)
    site.server.realtime = True
    client = RawClient(site.port)
    client.setup()
    started = time.perf_counter()
    n = 300
    for k in range(n):
        client.step(0.0, 0.0, (k + 1) * DT)
    wall = time.perf_counter() - started
    client.frame(99)
    assert site.join() == 0
    assert wall >= (n - 1) * DT  # never ahead of the simulated clock
    summary = site.server.sessions[-1]
    assert summary.steps == n
    assert math.isfinite(summary.quantile_us(0.5))


@pytest.mark.skipif(not socket.has_ipv6, reason="this machine has no IPv6")
def test_a_site_listens_on_the_ipv6_loopback():
    """``--host ::1`` binds an IPv6 socket (the default allow-list admits ::1) and serves a client there."""
    cmd = [sys.executable, "-m", "pendsweep.cli", "site", "--host", "::1", "--port", "0", "--once"]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    try:
        port = int(re.search(r"listening on ::1:(\d+)", proc.stderr.readline()).group(1))
        client = RawClient(port, host="::1")
        client.setup()
        assert math.isfinite(client.step(0.0, 0.0, 0.001))
        client.frame(99)
        client.close()
        assert proc.wait(timeout=60) == 0
    finally:
        proc.kill()
