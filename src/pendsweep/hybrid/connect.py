"""Reaching a site that may still be starting: ``tcp://HOST:PORT`` addresses and a bounded connect.

``pendsweep site`` loads its compiled kernels before it listens (about 2 s),
so a client started in the same breath (the next line of a shell block, a
script) finds nothing listening yet. A refused connection is therefore tried
again every :data:`RETRY_SECONDS` until :data:`CONNECT_DEADLINE` seconds have
passed; then the client fails with one line (exit status 1). The remote-rig
client (``-B rig=tcp://HOST:PORT``) connects this way, and ``pendsweep wait``
does it for clients that try once, such as OpenSees's ``genericClient``.

Only a refusal (nothing listens there yet) is retried: an address that does
not resolve or a host that does not answer fails as it did.

This module imports nothing numerical: ``pendsweep wait`` starts in a blink.
"""

from __future__ import annotations

import socket
import time
from urllib.parse import urlsplit

from ..errors import ConfigError, RunFailure

#: Seconds a client goes on trying a site that refuses connections (one that is still starting).
CONNECT_DEADLINE = 10.0
#: Seconds between two tries.
RETRY_SECONDS = 0.1


def parse_rig_url(url: str) -> tuple[str, int]:
    """``tcp://HOST:PORT`` as ``(host, port)``; anything else is a :class:`ConfigError`."""
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme != "tcp" or not parts.hostname or port is None or parts.path not in ("", "/"):
        raise ConfigError(f"rig = {url!r}; give tcp://HOST:PORT (e.g. tcp://127.0.0.1:8090) or leave it empty")
    return parts.hostname, port


def connect(
    host: str, port: int, timeout: float, deadline: float | None = None, what: str = "the rig"
) -> socket.socket:
    """A connected socket to ``host:port``, retrying refusals until ``deadline`` seconds have passed.

    Parameters
    ----------
    host, port : str, int
        The site's address.
    timeout : float
        Seconds one try may wait for the peer's answer (the socket keeps it).
    deadline : float or None
        Seconds to keep trying a refusing address; None: :data:`CONNECT_DEADLINE`
        (read at the call, so that tests can shorten it).
    what : str
        What the address is, for the message.

    Raises
    ------
    RunFailure
        Nothing accepted the connection within the deadline, or it failed otherwise.
    """
    deadline = CONNECT_DEADLINE if deadline is None else deadline
    give_up = time.monotonic() + deadline
    while True:
        try:
            return socket.create_connection((host, port), timeout=timeout)
        except ConnectionRefusedError as exc:  # nothing listens yet: a site still starting, so try again
            left = give_up - time.monotonic()
            if left <= 0.0:
                raise RunFailure(
                    f"cannot reach {what} at tcp://{host}:{port}: {exc.strerror or exc} "
                    f"(nothing listened there within {deadline:g} s)"
                ) from None
            time.sleep(min(RETRY_SECONDS, left))  # the last try falls on the deadline
        except OSError as exc:
            raise RunFailure(f"cannot reach {what} at tcp://{host}:{port}: {exc.strerror or exc}") from None
