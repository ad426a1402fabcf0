"""The substructured backend's controller driving a remote site: ``-B rig=tcp://HOST:PORT``.

Each tick the controller sends the command for the next tick as a trial
(displacement, its slope as velocity, acceleration 0, time), asks for the
daq response and commits, in one write: one round trip per tick. The set-up
asks for the daq vectors this loop needs: disp (LVDT x, encoder theta), vel
(x', theta'), accel, force (the load cell) and time, all of which a
``pendsweep site`` measures; a real rig's site must be configured to return
the same (the encoder as the second displacement channel).

The loop is the in-process one with the rig's half replaced by the reply
(the instability monitor reads the platform's acceleration from the daq
response instead of differencing positions):
:func:`~pendsweep.kernels._substructured.command_tick` is the same function,
so against a ``pendsweep site`` with the same rig options and noise-free
sensors the records are the in-process ones to rounding.

The protocol cannot put a specimen into a state, so a remote rig starts every
run from the site's own initial state (a new connection each run): a run must
start from a fresh state (ticks 0, platform at 0), which sweeps give in
``--mode fresh``; the pendulum's initial angle is the site's ``--theta0``.

A site that is still starting (nothing listens yet) is tried again for up to
:data:`~.connect.CONNECT_DEADLINE` seconds (10 s) before the run fails
(:func:`~.connect.connect`), so a client may be started with its site.
"""

from __future__ import annotations

import math
import socket
import struct
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError, RunFailure
from ..kernels import N_RECORD_COLUMNS
from ..kernels._emulated import forcing_table
from ..kernels._layout import STATUS_OK
from ..kernels._records import TWO_PI, record_open
from ..kernels._site import client_tick
from ..kernels._substructured import (
    S_THETA,
    S_THETADOT,
    S_TICKS,
    S_X,
    S_XDOT,
    S_Y,
    close_period,
    high_frequency_growth,
    stroke_status,
)
from .connect import connect, parse_rig_url
from .protocol import Action, FrameReader, ProtocolError, Setup, send_all

#: The set-up this client sends: ctrl disp, vel, accel, time; daq disp 2 (LVDT, encoder), vel 2, accel, force, time.
CLIENT_SETUP = Setup((1, 1, 1, 0, 1), (2, 2, 1, 1, 1), 16)
#: Seconds to wait for each try of a connection and for each reply (a site still starting is
#: retried for :data:`~.connect.CONNECT_DEADLINE` seconds).
CONNECT_TIMEOUT = 10.0
#: Largest magnitude of any daq value a rig may reply (SI units): beyond it the reply is garbage.
REPLY_LIMIT = 1e6


@dataclass
class RemoteRig:
    """One connection to a remote site, set up for :data:`CLIENT_SETUP`.

    Attributes
    ----------
    round_trips : list of float
        Seconds from each tick's request to its reply (the protocol's timing,
        kept in the backend's run statistics).
    """

    host: str
    port: int
    timeout: float = CONNECT_TIMEOUT
    round_trips: list[float] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.sock = connect(self.host, self.port, self.timeout)
        self.sock.settimeout(None)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, struct.pack("ll", int(self.timeout), 0))
        self.reader = FrameReader(self.sock, self.timeout)
        setup = CLIENT_SETUP
        self._frames = np.zeros((3, setup.data_size))  # commit, trial, getDaqResponse: one write
        self._frames[0, 0] = Action.COMMIT_STATE
        self._frames[1, 0] = Action.SET_TRIAL_RESPONSE
        self._frames[2, 0] = Action.GET_DAQ_RESPONSE
        self._out = memoryview(self._frames).cast("B")
        self._reply = np.zeros(setup.data_size)
        self._in = memoryview(self._reply).cast("B")
        self._send(memoryview(setup.pack()))
        self._send(self._out[2 * 8 * setup.data_size :])  # the reading before the first trial
        self._receive()

    def _send(self, data: memoryview) -> None:
        try:
            send_all(self.sock, data, self.timeout)
        except ProtocolError as exc:
            raise RunFailure(f"rig at tcp://{self.host}:{self.port}: {exc}") from None

    def _receive(self) -> None:
        try:
            self.reader.read(self._in, "reply")
        except ProtocolError as exc:
            raise RunFailure(f"rig at tcp://{self.host}:{self.port}: {str(exc).replace('client', 'site')}") from None
        # the site's bytes are as hostile as a client's: a reading that no rig can give stops the run
        values = self._reply[:7]
        if not np.all(np.isfinite(values)) or np.any(np.abs(values) > REPLY_LIMIT):
            raise RunFailure(
                f"rig at tcp://{self.host}:{self.port} replied {values.tolist()}: not finite or beyond "
                f"{REPLY_LIMIT:g} (x, theta, x', theta', x'', F, t)"
            )

    @property
    def reply(self) -> np.ndarray:
        """The last daq reply: x_meas, theta, x', theta', x'' (mean), F_s, t."""
        return self._reply

    def step(self, command: float, slope: float, t: float, commit: bool) -> np.ndarray:
        """Commit the last trial (unless it is the first), send the next, read its daq response."""
        f = self._frames
        f[1, 1], f[1, 2], f[1, 3], f[1, 4] = command, slope, 0.0, t
        start = time.perf_counter()
        self._send(self._out if commit else self._out[8 * f.shape[1] :])
        self._receive()
        self.round_trips.append(time.perf_counter() - start)
        return self._reply

    def abort(self) -> None:
        """Drop the connection at once (the site stops its rig safely on a lost client)."""
        self.sock.close()

    def close(self) -> None:
        """Commit the last trial and end the session (die)."""
        try:
            f = self._frames[:2].copy()
            f[1, :] = 0.0
            f[1, 0] = Action.DIE
            send_all(self.sock, memoryview(f).cast("B"), self.timeout)
        except ProtocolError:
            pass
        finally:
            self.sock.close()


def run_remote(backend, params, state, transient: int, n_rec: int, trace_rows: int, stride: int):
    """The substructured loop with the rig at ``backend.rig``.

    Returns ``(code, done, state, records, trace, round_trip)``, the last the
    50th, 99th percentile and largest round trip per tick [s].

    Mirrors :func:`~pendsweep.kernels._substructured.substructured_loop`
    tick for tick (see the module docstring for what a remote rig cannot do).
    """
    if state[S_TICKS] != 0 or state[S_X] != 0 or state[S_Y] != 0:
        raise ConfigError(
            "a remote rig starts every run from the site's initial state (platform at 0): start from y = 0 "
            "with a fresh state (sweeps: --mode fresh)"
        )
    host, port = parse_rig_url(backend.rig)
    cfg = backend.loop_settings(params)
    p = params.kernel_array()
    n = cfg.steps_per_period
    dt = 1.0 / (cfg.fe * n)
    we = TWO_PI * cfg.fe
    table = forcing_table(cfg.alpha, n)
    records = np.full((n_rec, N_RECORD_COLUMNS), np.nan)
    trace = np.full((trace_rows, 15), np.nan)
    no_row = np.empty(0)
    row = np.empty(N_RECORD_COLUMNS)
    rig = RemoteRig(host, port)
    turns_total = 0
    status, hf_run, done, tick = STATUS_OK, 0, 0, 0
    readings = np.empty(4)  # f_meas, fs_true (not measured remotely), theta_x, x_meas

    def take(reply: np.ndarray) -> None:
        x_meas, th_x, xd, thd, _acc, f_meas = reply[:6]
        state[S_X], state[S_XDOT], state[S_THETA], state[S_THETADOT] = x_meas, xd, th_x - TWO_PI * turns_total, thd
        readings[0], readings[1], readings[2], readings[3] = f_meas, math.nan, state[S_THETA], x_meas

    try:
        take(rig.reply)
        for period in range(transient + n_rec):
            record_open(row)
            sum_x2 = sum_h2 = 0.0
            for jstep in range(n):
                k = period * n + jstep
                tr = trace[k // stride] if trace_rows and k % stride == 0 else no_row
                command, slope = client_tick(state, p, cfg, table, jstep, k, readings, row, tr)
                reply = rig.step(command, slope, (k + 1) * dt, commit=k > 0)
                take(reply)
                tick += 1
                x = state[S_X]
                # the high-frequency monitor takes x'' from the daq acceleration: a second difference
                # of the LVDT would measure its noise (20 um / dt^2 = 20 m/s^2), not the platform
                d2 = reply[4] * dt * dt
                sum_x2 += x * x
                sum_h2 += d2 * d2
                status = stroke_status(x, state[S_Y], cfg.stroke)
                if status != STATUS_OK:
                    break
            if status == STATUS_OK:
                hf_run = hf_run + 1 if high_frequency_growth(sum_x2, sum_h2, n, dt, we, cfg) else 0
            before = state[S_THETA]
            status, hf_run = close_period(state, row, records, period - transient, status, hf_run, trace_rows > 0, cfg)
            turns_total += int(round((before - state[S_THETA]) / TWO_PI))
            if status != STATUS_OK:
                break
            done = period + 1
    finally:
        rig.close()
    state[S_TICKS] += tick
    trips = np.asarray(rig.round_trips) if rig.round_trips else np.full(1, np.nan)
    timing = np.array([np.quantile(trips, 0.5), np.quantile(trips, 0.99), trips.max()])
    return status, done, state, records, trace, timing


class TcpTransport:
    """The :class:`~pendsweep.backends.transports.RigTransport` for ``tcp://HOST:PORT``: OpenFresco's protocol.

    Declared as the entry point ``tcp`` of ``pendsweep.rig_transports``, so a
    substructured backend with ``rig = tcp://...`` finds it without
    importing this module.
    """

    def check(self, url: str) -> None:
        parse_rig_url(url)

    def run(self, backend, params, state, transient: int, n_rec: int, trace_rows: int, stride: int):
        return run_remote(backend, params, state, transient, n_rec, trace_rows, stride)

    def open(self, url: str) -> RemoteRig:
        return RemoteRig(*parse_rig_url(url))


#: The transport the ``tcp`` entry point names.
TCP_TRANSPORT = TcpTransport()
