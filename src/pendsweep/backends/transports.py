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
    """

    def check(self, url: str) -> None: ...

    def run(
        self, backend: Any, params: ModelParams, state: np.ndarray, transient: int, n_rec: int,
        trace_rows: int, stride: int,
    ) -> tuple: ...  # fmt: skip


_TRANSPORTS: dict[str, RigTransport] = {}


def register_rig_transport(scheme: str, transport: RigTransport) -> None:
    """Hand in ``transport`` for rigs at ``scheme://...`` (replaces an earlier one of that scheme)."""
    _TRANSPORTS[scheme] = transport


def rig_transport(url: str) -> RigTransport:
    """The transport for ``url``'s scheme, checked against ``url``; a :class:`ConfigError` if there is none."""
    scheme = urlsplit(url).scheme
    if scheme not in _TRANSPORTS:
        for point in entry_points(group=ENTRY_POINT_GROUP, name=scheme):
            register_rig_transport(scheme, point.load())
    if scheme not in _TRANSPORTS:
        installed = ", ".join(sorted(set(_TRANSPORTS) | {p.name for p in entry_points(group=ENTRY_POINT_GROUP)}))
        raise ConfigError(
            f"rig = {url!r}; give tcp://HOST:PORT (e.g. tcp://127.0.0.1:8090) or leave it empty "
            f"(transports installed: {installed or 'none'})"
        )
    transport = _TRANSPORTS[scheme]
    transport.check(url)
    return transport
