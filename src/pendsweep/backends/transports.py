"""How the substructured loop reaches a remote rig: transports handed in by URL scheme.

The backends open no sockets and import no client. A remote rig (``-B
rig=SCHEME://...``) is reached through a :class:`RigTransport` registered
for the URL's scheme, either

* in this process: :func:`register_rig_transport` (a test's fake rig, a
  lab's own link), or
* by a package's entry point in the group ``pendsweep.rig_transports``,
  loaded the first time its scheme is asked for. pendsweep declares
  ``tcp = pendsweep.hybrid.client:TCP_TRANSPORT`` (OpenFresco's protocol) in
  its ``pyproject.toml``: that declaration is how the hybrid-testing layer
  hands its client to the backend without the backend importing it.
"""

from __future__ import annotations

from importlib.metadata import entry_points
from typing import TYPE_CHECKING, Any, Protocol
from urllib.parse import urlsplit

from ..errors import ConfigError

if TYPE_CHECKING:
    import numpy as np

    from ..model.params import ModelParams

#: Entry-point group a package declares its transports in (name: the URL scheme).
ENTRY_POINT_GROUP = "pendsweep.rig_transports"


class RigTransport(Protocol):
    """A remote rig's link, the half of the substructured loop that is not in this process.

    1. ``check(url)`` raises :class:`~pendsweep.errors.ConfigError` (one line)
       for an address it cannot use; called when the backend is built.
    2. ``run(backend, params, state, transient, n_rec, trace_rows, stride)``
       runs the loop against the rig and returns what the in-process loop
       returns: ``(code, done, state, records, trace, round_trip)``, the last
       the 50th, 99th percentile and largest round trip per tick [s].
    3. Optionally ``open(url)``: a :class:`RigLink`, one connection held for a
       whole continuous test (a sweep in ``--mode continue``,
       :class:`pendsweep.hybrid.session.RigSession`). A transport without it
       runs single points only, and a continuous test on it is refused
       before it starts.
    """

    def check(self, url: str) -> None: ...

    def run(
        self, backend: Any, params: ModelParams, state: np.ndarray, transient: int, n_rec: int,
        trace_rows: int, stride: int,
    ) -> tuple: ...  # fmt: skip


class RigLink(Protocol):
    """One connection to a rig, tick by tick (:meth:`RigTransport.open`).

    ``reply`` is the last daq reply, float64[7]: measured platform
    displacement [m], encoder angle [rad], platform and pendulum velocities
    [m/s, rad/s], platform acceleration [m/s^2], load-cell force [N], time [s].
    ``step`` commits the last trial (unless ``commit`` is False, the first),
    sends the next command [m] with its slope [m/s] for time ``t`` [s] and
    returns the reply; ``round_trips`` holds each step's seconds. ``close``
    ends the session normally; ``abort`` drops the connection at once.
    """

    round_trips: list[float]

    @property
    def reply(self) -> np.ndarray: ...

    def step(self, command: float, slope: float, t: float, commit: bool) -> np.ndarray: ...

    def close(self) -> None: ...

    def abort(self) -> None: ...


_TRANSPORTS: dict[str, RigTransport] = {}


def register_rig_transport(scheme: str, transport: RigTransport) -> None:
    """Hand in ``transport`` for rigs at ``scheme://...`` (replaces an earlier one of that scheme)."""
    _TRANSPORTS[scheme] = transport


def rig_transport(url: str) -> RigTransport:
    """The transport for ``url``'s scheme, checked against ``url``; a :class:`ConfigError` if there is none."""
    scheme = urlsplit(url).scheme
    if scheme not in _TRANSPORTS:
        for point in entry_points(group=ENTRY_POINT_GROUP, name=scheme):
            try:
                register_rig_transport(scheme, point.load())
            except Exception as exc:  # a broken plug-in is the installation's fault: say which, in one line
                raise ConfigError(f"rig = {url!r}: the transport {point.value} ({point.group}) does not load: "
                                  f"{type(exc).__name__}: {exc}") from None  # fmt: skip
    if scheme not in _TRANSPORTS:
        installed = ", ".join(sorted(set(_TRANSPORTS) | {p.name for p in entry_points(group=ENTRY_POINT_GROUP)}))
        raise ConfigError(
            f"rig = {url!r}; give tcp://HOST:PORT (e.g. tcp://127.0.0.1:8090) or leave it empty "
            f"(transports installed: {installed or 'none'})"
        )
    transport = _TRANSPORTS[scheme]
    transport.check(url)
    return transport


def continuous_transport(url: str) -> RigTransport:
    """The transport for ``url``, refused (:class:`ConfigError`) if it cannot hold a continuous test (no ``open``)."""
    transport = rig_transport(url)
    if not callable(getattr(transport, "open", None)):
        raise ConfigError(
            f"rig = {url!r}: its transport runs single points only (no open()): use --mode fresh, "
            "or give the transport a connection for a whole test (pendsweep.backends.transports.RigTransport)"
        )
    return transport
