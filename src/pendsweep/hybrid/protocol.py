"""OpenFresco's remote-test protocol over TCP, as OpenSees's ``genericClient`` element speaks it.

The wire format (OpenSees ``SRC/element/generic/GenericClient.cpp``, OpenFresco
``RemoteExpSite``), little-endian as on every machine OpenSees is built for:

1. **Set-up**, once, client to site: 11 int32, ``sizeCtrl`` (disp, vel, accel,
   force, time), ``sizeDaq`` (disp, vel, accel, force, time), ``dataSize``.
   OpenSees sends ``(1, 1, 1, 0, 1, 0, 0, 0, 1, 0, 256)`` for one degree of
   freedom. The site sends nothing back.
2. **Frames**, each exactly ``dataSize`` float64, whose first entry is the
   action (:class:`Action`). A trial (3) carries the control vectors after the
   action: disp, vel, accel, force, time, each of its ``sizeCtrl`` length.
   getForce (10) is answered with ``dataSize`` float64, the forces first;
   getDaqResponse (6) with the daq vectors concatenated (disp, vel, accel,
   force, time); the matrix actions (12-15) with the ``n x n`` matrix,
   column-major, first. commitState (5) and die (99) are not answered.

Every byte from the socket is hostile: :func:`parse_setup` bounds every size
before anything is allocated, :class:`FrameReader` has a deadline on every read, and every
violation raises :class:`ProtocolError` with a one-line reason.
"""

from __future__ import annotations

import enum
import os
import select
import socket
import struct
import time
from dataclasses import dataclass

import numpy as np

from ..errors import RunFailure

SETUP_INTS = 11
SETUP_BYTES = 4 * SETUP_INTS
#: Largest ``dataSize`` accepted [float64 per frame]: 1 MiB frames. OpenSees sends 256.
MAX_DATA_SIZE = 131072
#: Largest size of any one control or daq vector in the set-up message.
MAX_VECTOR_SIZE = 64
QUANTITIES = ("disp", "vel", "accel", "force", "time")


class Action(enum.IntEnum):
    """The actions of OpenFresco's remote test (``RemoteTest_*`` in GenericClient.h)."""

    SET_TRIAL_RESPONSE = 3
    COMMIT_STATE = 5
    GET_DAQ_RESPONSE = 6
    GET_DISP = 7
    GET_VEL = 8
    GET_ACCEL = 9
    GET_FORCE = 10
    GET_TIME = 11
    GET_INITIAL_STIFF = 12
    GET_TANGENT_STIFF = 13
    GET_DAMP = 14
    GET_MASS = 15
    DIE = 99


ACTIONS = frozenset(int(a) for a in Action)


class ProtocolError(RunFailure):
    """The peer broke the protocol or the rig's limits; the message is the one-line reason."""


@dataclass(frozen=True)
class Setup:
    """The sizes of the set-up message.

    Attributes
    ----------
    ctrl : tuple of 5 int
        Lengths of the control vectors a trial carries (disp, vel, accel, force, time).
    daq : tuple of 5 int
        Lengths of the measured vectors getDaqResponse returns, in the same order.
    data_size : int
        float64 per frame, both ways.
    """

    ctrl: tuple[int, int, int, int, int]
    daq: tuple[int, int, int, int, int]
    data_size: int

    def pack(self) -> bytes:
        return struct.pack("<11i", *self.ctrl, *self.daq, self.data_size)

    @property
    def frame_bytes(self) -> int:
        return 8 * self.data_size

    def ctrl_slices(self) -> dict[str, slice]:
        """Where each control quantity sits in a trial frame (after the action)."""
        out, at = {}, 1
        for name, size in zip(QUANTITIES, self.ctrl):
            out[name] = slice(at, at + size)
            at += size
        return out


def parse_setup(raw: bytes, *, dofs: int = 1, daq_limits=(2, 2, 1, 1, 1)) -> Setup:
    """Validate a set-up message for a site of ``dofs`` controlled degrees of freedom.

    ``daq_limits`` are the longest daq vectors the site can measure. Raises
    :class:`ProtocolError` naming the first size out of range.
    """
    if len(raw) != SETUP_BYTES:
        raise ProtocolError(f"set-up message of {len(raw)} bytes; expected {SETUP_BYTES} (11 int32)")
    values = struct.unpack("<11i", raw)
    ctrl, daq, data_size = values[:5], values[5:10], values[10]
    for group, sizes in (("sizeCtrl", ctrl), ("sizeDaq", daq)):
        for name, size in zip(QUANTITIES, sizes):
            if not 0 <= size <= MAX_VECTOR_SIZE:
                raise ProtocolError(f"set-up {group}.{name} = {size}; accepted 0..{MAX_VECTOR_SIZE}")
    if ctrl[0] != dofs:
        raise ProtocolError(f"set-up sizeCtrl.disp = {ctrl[0]}; this site controls {dofs} degree(s) of freedom")
    for name, size in zip(QUANTITIES[1:3], ctrl[1:3]):
        if size not in (0, dofs):
            raise ProtocolError(f"set-up sizeCtrl.{name} = {size}; accepted 0 or {dofs}")
    if ctrl[3] != 0:
        raise ProtocolError(f"set-up sizeCtrl.force = {ctrl[3]}; this site is displacement-controlled (accepted 0)")
    if ctrl[4] not in (0, 1):
        raise ProtocolError(f"set-up sizeCtrl.time = {ctrl[4]}; accepted 0 or 1")
    for name, size, limit in zip(QUANTITIES, daq, daq_limits):
        if size > limit:
            raise ProtocolError(f"set-up sizeDaq.{name} = {size}; this site measures at most {limit}")
    need = max(1 + sum(ctrl), sum(daq), dofs * dofs, 1)
    if not need <= data_size <= MAX_DATA_SIZE:
        raise ProtocolError(f"set-up dataSize = {data_size}; accepted {need}..{MAX_DATA_SIZE} float64 per frame")
    return Setup(tuple(ctrl), tuple(daq), data_size)


def opensees_setup(dofs: int = 1, data_size: int = 256) -> Setup:
    """The set-up message OpenSees's genericClient sends for ``dofs`` degrees of freedom."""
    return Setup((dofs, dofs, dofs, 0, 1), (0, 0, 0, dofs, 0), max(data_size, 1 + 3 * dofs + 1, dofs * dofs))


def quickack(sock: socket.socket) -> None:
    """Acknowledge at once (Linux ``TCP_QUICKACK``, which the kernel clears after each receive).

    OpenSees does not set ``TCP_NODELAY``: its next frame waits for our
    acknowledgement, and a delayed one costs about 40 ms a step.
    """
    if _QUICKACK is not None:
        sock.setsockopt(socket.IPPROTO_TCP, _QUICKACK, 1)


_QUICKACK = getattr(socket, "TCP_QUICKACK", None)


def tune(sock: socket.socket, timeout: float) -> None:
    """Options for a connected socket: blocking, no Nagle delay, immediate ACKs, sends bounded by ``timeout`` [s]."""
    sock.settimeout(None)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    seconds = int(timeout)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, struct.pack("ll", seconds, int((timeout - seconds) * 1e6)))
    quickack(sock)


#: Seconds a reader polls a silent socket before it blocks. Blocking costs a process wake-up per
#: message (tens of microseconds on a loaded machine; OpenSees's genericClient exchanges about
#: seven messages a step); polling answers at once, at the cost of one busy core while a client is served.
SPIN_SECONDS = 2e-3
#: Polling yields the processor after this long [s]: a peer that answers within it is on another core.
YIELD_AFTER_SECONDS = 1e-4


class FrameReader:
    """Reads whole messages from a connected socket: polls for ``spin`` seconds, then waits.

    Every read has a deadline of ``timeout`` seconds in all; the peer closing
    mid-message, staying silent past the deadline or the connection failing
    raise :class:`ProtocolError` with a one-line reason. The socket stays in
    blocking mode without a Python timeout, because CPython then polls before
    every send and receive (a system call each); the wait uses ``select`` and
    sends are bounded by the kernel's ``SO_SNDTIMEO`` (:func:`tune`).
    """

    def __init__(self, sock: socket.socket, timeout: float, spin: float = SPIN_SECONDS) -> None:
        self.sock = sock
        self.timeout = timeout
        self.spin = spin

    def read(self, view: memoryview, what: str) -> None:
        """Fill ``view`` (bytes) from the socket."""
        sock = self.sock
        want = len(view)
        got = 0
        started = time.perf_counter()
        while got < want:
            try:
                n = sock.recv_into(view[got:], want - got, _DONTWAIT)
            except BlockingIOError:
                waited = time.perf_counter() - started
                if waited > self.spin:
                    left = self.timeout - waited
                    if left <= 0 or not select.select([sock], [], [], left)[0]:
                        state = "silent" if got == 0 else "too slow"
                        raise ProtocolError(
                            f"client {state}: {what} not complete within {self.timeout:g} s ({got} of {want} bytes)"
                        ) from None
                elif waited > YIELD_AFTER_SECONDS:
                    os.sched_yield()  # a slow peer may need this core: give way to any process that can run
                continue
            except OSError as exc:
                raise ProtocolError(f"connection failed while reading {what}: {exc.strerror or exc}") from None
            if n == 0:
                if got == 0 and what == "frame":
                    raise ProtocolError("client closed the connection without a die message")
                raise ProtocolError(f"client closed the connection mid-{what.split()[0]} ({got} of {want} bytes)")
            got += n
            quickack(sock)


def send_all(sock: socket.socket, data: memoryview, timeout: float) -> None:
    """Send ``data``; a peer that does not read for ``timeout`` seconds (``SO_SNDTIMEO``) is a fault."""
    try:
        sock.sendall(data)
    except BlockingIOError:
        raise ProtocolError(f"client stopped reading replies for more than {timeout:g} s") from None
    except OSError as exc:
        raise ProtocolError(f"connection failed while replying: {exc.strerror or exc}") from None


_DONTWAIT = getattr(socket, "MSG_DONTWAIT", 0)


def frame_buffer(setup: Setup) -> np.ndarray:
    """A zeroed float64 frame of ``setup.data_size``."""
    return np.zeros(setup.data_size, dtype="<f8")
