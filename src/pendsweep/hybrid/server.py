"""``pendsweep site``: serve the virtual rig to one remote-test client at a time.

One session is one client: set-up, then frames until die. The dispatch per
action (see :mod:`.protocol` for the wire format):

============================  =====================================================
action                        what the site does
============================  =====================================================
3 setTrialResponse            rebuild the trial state from the committed rig
                              (:meth:`SiteRig.trial`); no reply
5 commitState                 keep the trial state, log one row; no reply
6 getDaqResponse              disp (LVDT x, encoder theta), vel (x', theta'),
                              accel (mean x'' over the step), force (load cell),
                              time: as many of each as the set-up asked for
7, 8, 9, 11                   the same quantities one by one
10 getForce                   the force of :meth:`SiteRig.force`
12, 13 stiffness              0 (the platform rides on bearings; the pendulum's
                              coupling is dynamic, not a stiffness)
14 getDamp                    0 (C2's force is measured, not modelled)
15 getMass                    ``M2 + m`` with ``report_mass`` (default), else 0
99 die                        the session ends normally
============================  =====================================================

Anything else ends the session with a one-line reason (:class:`ProtocolError`):
the rig is held at its committed state, the log up to the last committed
step is written, and with ``once`` the site exits with status 1. A second
client that connects while one is served is told nothing and closed, with a
line on stderr; the session in progress goes on. So is a client whose address
is outside the allow-list (:mod:`.access`), at whatever moment it connects:
before a byte of its set-up is read, kept in the log's metadata, never a
session (it neither ends a ``once`` site nor counts as its client).
"""

from __future__ import annotations

import gc
import math
import select
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .access import LOOPBACK_NETWORKS, Network, admits
from .log import SiteLog
from .protocol import (
    ACTIONS,
    SETUP_BYTES,
    Action,
    FrameReader,
    ProtocolError,
    Setup,
    frame_buffer,
    parse_setup,
    quickack,
    send_all,
    tune,
)
from .rig import READING_INDEX, SiteRig

#: Waits shorter than this [s] spin instead of sleeping: a process woken from sleep on a shared
#: virtual machine is sometimes scheduled a millisecond late, a whole step at 1 kHz.
SPIN_SECONDS = 5e-3
#: Seconds a new connection has to send its first byte or close: one that closes unheard is a
#: readiness probe (``pendsweep wait``, ``nc -z``), which must neither end a ``--once`` site nor enter
#: its log. A client sends its set-up at once; a silent one only starts its session this much later.
PROBE_SECONDS = 0.5

DAQ_SOURCES = {  # daq quantity -> reading names, in the order they are sent
    "disp": ("x_meas", "theta"),
    "vel": ("xdot", "thetadot"),
    "accel": ("xddot_mean",),
    "force": ("Fs",),
}


@dataclass
class SessionSummary:
    """How one client's session went."""

    peer: str
    steps: int = 0
    wall: float = 0.0
    simulated: float = 0.0
    service: list[float] = field(default_factory=list)
    misses: int = 0
    reason: str = "die"
    ok: bool = True
    interrupted: bool = False

    def quantile_us(self, q: float) -> float:
        """Quantile ``q`` of the service times [us] of the steps whose force was asked for."""
        times = np.asarray(self.service)
        times = times[np.isfinite(times)]
        return float(np.quantile(times, q) * 1e6) if times.size else math.nan

    def line(self) -> str:
        speed = self.simulated / self.wall if self.wall > 0 else math.nan
        text = (
            f"client {self.peer} left after {self.steps} steps ({self.simulated:.6g} s simulated) in "
            f"{self.wall:.3f} s wall, {speed:.2f}x real time; service time p50 {self.quantile_us(0.5):.1f} us, "
            f"p99 {self.quantile_us(0.99):.1f} us; deadline misses {self.misses}"
        )
        return text if self.ok else f"{text}; stopped: {self.reason}"

    def to_dict(self) -> dict:
        return {
            "peer": self.peer,
            "steps": self.steps,
            "wall_s": self.wall,
            "simulated_s": self.simulated,
            "service_p50_s": self.quantile_us(0.5) * 1e-6,
            "service_p99_s": self.quantile_us(0.99) * 1e-6,
            "deadline_misses": self.misses,
            "ended": "die" if self.ok else "fault",
            "reason": self.reason,
        }


def _say(text: str) -> None:
    print(f"pendsweep site: {text}", file=sys.stderr, flush=True)


class _Pacer:
    """Real-time pacing: a step's force is not sent before its simulated time has passed on the wall clock.

    The clock starts at the first step (wall ``w0`` = simulated time 0 of the
    trial before it); a force sent more than one step after its time is a
    deadline miss.
    """

    def __init__(self) -> None:
        self.origin: float | None = None

    def wait(self, t: float, dt: float) -> tuple[bool, float]:
        """Hold until simulated time ``t`` [s] on the wall clock.

        Returns whether ``t + dt`` had already passed (a miss) and the seconds held.
        """
        now = time.perf_counter()
        if self.origin is None:
            self.origin = now - (t - dt)
        target = self.origin + t
        late = now > target + dt
        left = target - now
        if left > SPIN_SECONDS:
            time.sleep(left - SPIN_SECONDS)
        while time.perf_counter() < target:
            pass
        return late, max(left, 0.0)


class _Refuser(threading.Thread):
    """Accepts every client; closes at once those outside the allow-list and those that connect while a session runs.

    The rig has one controller, and only an allowed address may be it. A
    refusal happens here, in the accepting thread, so a session in progress
    never waits for one.
    """

    def __init__(self, listener: socket.socket, allow: tuple[Network, ...], log: SiteLog) -> None:
        super().__init__(daemon=True)
        self.listener = listener
        self.allow = allow
        self.log = log
        self.busy = threading.Event()
        self.pending: list[socket.socket] = []
        self.lock = threading.Lock()

    def run(self) -> None:
        while True:
            try:
                conn, addr = self.listener.accept()
            except OSError:
                return
            if not admits(self.allow, addr[0]):
                conn.close()  # before a byte is read: an unknown host's set-up never reaches the parser
                _say(f"refused client {addr[0]}:{addr[1]}: its address is not in the allow-list (--allow)")
                self.log.refuse(f"{addr[0]}:{addr[1]}", "address not in the allow-list")
            elif self.busy.is_set():
                _say(f"refused a second client {addr[0]}:{addr[1]}: a session is in progress")
                conn.close()
            else:
                with self.lock:
                    self.pending.append(conn)

    def next_client(self, poll: Callable[[], bool]) -> socket.socket | None:
        """Wait for a client; None when ``poll()`` says to stop."""
        while not poll():
            with self.lock:
                if self.pending:
                    self.busy.set()
                    return self.pending.pop(0)
            time.sleep(0.01)
        return None


def closed_unheard(conn: socket.socket, within: float = PROBE_SECONDS) -> bool:
    """Whether the peer closed ``conn`` before sending a byte: a readiness probe, not a client.

    Waits up to ``within`` seconds for the first byte or the close; a peer
    silent for longer is served as a client (and times out as one).
    """
    try:
        if not select.select([conn], [], [], within)[0]:
            return False
        return not conn.recv(1, socket.MSG_PEEK)
    except OSError:  # reset before its first byte: gone without a word, as a probe
        return True


def serve_session(conn: socket.socket, rig: SiteRig, log: SiteLog, timeout: float, realtime: bool) -> SessionSummary:
    """Serve one connected client until die or a fault (see the module docstring)."""
    try:
        host, port = conn.getpeername()[:2]
        peer = f"{host}:{port}"
    except OSError:  # the client already left
        peer = "unknown"
    summary = SessionSummary(peer)
    rig.reset()
    log.start_session()
    start = time.perf_counter()
    pacer = _Pacer() if realtime else None
    gc_was_enabled = gc.isenabled()
    gc.disable()  # a session allocates no cycles; a collection mid-step would be a latency spike
    try:
        tune(conn, timeout)
        reader = FrameReader(conn, timeout)
        raw = bytearray(SETUP_BYTES)
        reader.read(memoryview(raw), "set-up message")
        setup = parse_setup(bytes(raw))
        _serve_frames(conn, reader, setup, rig, log, summary, pacer)
    except ProtocolError as exc:
        summary.ok = False
        summary.reason = str(exc)
    except KeyboardInterrupt:  # SIGINT or SIGTERM mid-session: the session is recorded, then the site stops
        summary.ok = False
        summary.reason = "the site was stopped by a signal"
        summary.interrupted = True
    except Exception as exc:  # a defect of the site itself: one line, the session ends, the site goes on
        summary.ok = False
        summary.reason = f"internal error ({type(exc).__name__}: {exc})".replace("\n", " ")
    finally:
        if gc_was_enabled:
            gc.enable()
        summary.wall = time.perf_counter() - start
        summary.simulated = rig.committed_time
        conn.close()
    return summary


def _serve_frames(conn, reader: FrameReader, setup: Setup, rig: SiteRig, log: SiteLog, summary, pacer) -> None:
    frame = frame_buffer(setup)
    view = memoryview(frame).cast("B")
    reply = frame_buffer(setup)
    reply_bytes = memoryview(reply).cast("B")
    slices = setup.ctrl_slices()
    has_vel, has_acc, has_time = setup.ctrl[1] > 0, setup.ctrl[2] > 0, setup.ctrl[4] > 0
    d_at, v_at, a_at, t_at = slices["disp"].start, slices["vel"].start, slices["accel"].start, slices["time"].start
    received = 0.0
    service = math.nan
    late = False
    held = 0.0
    while True:
        reader.read(view, "frame")
        code = float(frame[0])
        if not (math.isfinite(code) and code == int(code) and int(code) in ACTIONS):
            raise ProtocolError(f"unknown action {code!r} after {summary.steps} committed steps")
        action = int(code)
        if action == Action.SET_TRIAL_RESPONSE:
            received = time.perf_counter()
            t = float(frame[t_at]) if has_time else None
            rig.trial(
                float(frame[d_at]),
                float(frame[v_at]) if has_vel else 0.0,
                float(frame[a_at]) if has_acc else 0.0,
                t,
            )
            continue
        if action == Action.COMMIT_STATE:
            if rig.commit():
                summary.steps += 1
                summary.service.append(service)
                summary.misses += late
                log.append(rig, service, received - log.session_start, late)
            service, late, held = math.nan, False, 0.0
            continue
        if action == Action.DIE:
            return
        if pacer is not None and action in (Action.GET_FORCE, Action.GET_DAQ_RESPONSE) and rig.dt is not None:
            miss, held = pacer.wait(rig.trial_time, rig.dt)
            late = late or miss
        _fill_reply(action, reply, rig, setup)
        send_all(conn, reply_bytes, reader.timeout)
        if action in (Action.GET_FORCE, Action.GET_DAQ_RESPONSE) and received:
            service = time.perf_counter() - received - held  # the real-time hold is not service
        quickack(conn)


def _fill_reply(action: int, reply: np.ndarray, rig: SiteRig, setup: Setup) -> None:
    reply[:] = 0.0
    r = rig.readings
    if action == Action.GET_FORCE:
        reply[0] = rig.force()
    elif action == Action.GET_MASS:
        reply[0] = rig.mass()
    elif action == Action.GET_DAQ_RESPONSE:
        at = 0
        for name, size in zip(("disp", "vel", "accel", "force", "time"), setup.daq):
            values = [rig.trial_time] if name == "time" else [r[READING_INDEX[n]] for n in DAQ_SOURCES[name]]
            reply[at : at + size] = values[:size]
            at += size
    elif action in (Action.GET_DISP, Action.GET_VEL, Action.GET_ACCEL):
        name = {Action.GET_DISP: "disp", Action.GET_VEL: "vel", Action.GET_ACCEL: "accel"}[Action(action)]
        values = [r[READING_INDEX[n]] for n in DAQ_SOURCES[name]]
        reply[: len(values)] = values
    elif action == Action.GET_TIME:
        reply[0] = rig.trial_time
    # 12, 13 (stiffness) and 14 (damping): zero, see the module docstring


@dataclass
class SiteServer:
    """A listening site: ``serve()`` runs sessions until told to stop (or after one with ``once``).

    Attributes
    ----------
    rig : SiteRig
    log : SiteLog
    host : str
        Address to listen on (default loopback only).
    allow : tuple of IPv4Network or IPv6Network
        Client addresses served (default loopback only); others are closed at connect.
    port : int
        0: the system picks a free port (printed on stderr, and in :attr:`address`).
    once : bool
        Serve one client, then return its exit status.
    timeout : float
        A client silent for longer [s] is a fault.
    realtime : bool
        Pace steps to the wall clock and count deadline misses.
    """

    rig: SiteRig
    log: SiteLog
    host: str = "127.0.0.1"
    allow: tuple[Network, ...] = LOOPBACK_NETWORKS
    port: int = 0
    once: bool = False
    timeout: float = 10.0
    realtime: bool = False
    stop: threading.Event = field(default_factory=threading.Event)
    sessions: list[SessionSummary] = field(default_factory=list)

    def __post_init__(self) -> None:
        # Load the rig's compiled kernels now: the first client must not wait for them (1-2 s).
        # (One millisecond, a step inside the accepted range whatever -B dt says.)
        self.rig.trial(0.0, 0.0, 0.0, 1e-3)
        self.rig.reset()
        # the address's own family: an IPv6 host (::1, ::) needs an IPv6 socket, create_server's default is IPv4
        family = socket.getaddrinfo(self.host, self.port, type=socket.SOCK_STREAM)[0][0]
        self.listener = socket.create_server((self.host, self.port), family=family, reuse_port=False, backlog=4)
        self.address = self.listener.getsockname()[:2]

    def serve(self) -> int:
        """Run sessions; returns the exit status (0: the last session ended with die, 1: with a fault)."""
        refuser = _Refuser(self.listener, self.allow, self.log)
        refuser.start()
        rig = self.rig
        mass = f"mass {rig.mass():g} kg reported" if rig.report_mass else "no mass reported"
        _say(
            f"listening on {self.address[0]}:{self.address[1]} ({rig.backend.actuator} actuator, {mass}, "
            f"timeout {self.timeout:g} s{', real time' if self.realtime else ''})"
        )
        status = 0
        try:
            while not self.stop.is_set():
                conn = refuser.next_client(self.stop.is_set)
                if conn is None:
                    break
                if closed_unheard(conn):  # a readiness probe (pendsweep wait): no session, the site goes on
                    conn.close()
                    refuser.busy.clear()
                    continue
                summary = serve_session(conn, rig, self.log, self.timeout, self.realtime)
                refuser.busy.clear()
                self.sessions.append(summary)
                self.log.end_session(summary)
                self.log.write()
                _say(summary.line())
                status = 0 if summary.ok else 1
                if summary.interrupted:
                    raise KeyboardInterrupt
                if self.once:
                    break
        finally:
            self.listener.close()
            self.log.write()
        return status
