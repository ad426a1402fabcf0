"""Who may drive the rig: the site's allow-list of client addresses (``pendsweep site --allow``).

A client of the site moves the actuator, so the site serves only the
addresses it was told to. The default is loopback only (127.0.0.0/8 and ::1,
also seen as IPv4-mapped ``::ffff:127.x.y.z`` on a dual-stack socket): a site
bound beyond loopback without ``--allow`` still serves only clients on its own
machine, and says so once at start (:func:`loopback_only_warning`). Given
networks replace the default rather than add to it, so that ``--allow
127.0.0.1`` means that one address. A client outside the list is closed at
connect, before a byte of its set-up is read (see :mod:`.server`).

The list checks the source address only: the protocol has no authentication,
so this keeps out mistakes and strangers on a lab network, not someone who can
forge addresses on it.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Iterable

from ..errors import ConfigError

Network = ipaddress.IPv4Network | ipaddress.IPv6Network

#: Whom a site serves when ``--allow`` is not given: its own machine.
LOOPBACK_NETWORKS: tuple[Network, ...] = (ipaddress.ip_network("127.0.0.0/8"), ipaddress.ip_network("::1/128"))

_ACCEPTED = "an IPv4 or IPv6 address or CIDR network (e.g. 192.168.10.20, 192.168.10.0/24, fd00::/64)"


def parse_allow(values: Iterable[str]) -> tuple[Network, ...]:
    """The networks of ``--allow`` values, each one address or network or several separated by commas.

    Parameters
    ----------
    values : iterable of str
        The option's values as given (repeated options and comma-separated
        items alike); an address is the network of that one address.

    Returns
    -------
    tuple of IPv4Network or IPv6Network
        In the order given.

    Raises
    ------
    ConfigError
        (exit 2) naming the first item that is not an address or network. A
        network with host bits set (``10.0.0.1/24``) is refused rather than
        widened, since it reads as either the address or the network.
    """
    return tuple(_network(item.strip()) for value in values for item in value.split(","))


def _network(text: str) -> Network:
    try:
        return ipaddress.ip_network(text)
    except ValueError:
        pass
    try:
        widened = ipaddress.ip_network(text, strict=False)
    except ValueError:
        raise ConfigError(f"--allow {text!r} is not {_ACCEPTED}") from None
    raise ConfigError(
        f"--allow {text!r} has host bits set: give the network {widened} or the address {text.split('/')[0]}"
    )


def admits(networks: Iterable[Network], host: str) -> bool:
    """Whether a client at ``host`` (an address as ``accept`` reports it) is in ``networks``.

    An IPv4-mapped IPv6 address, how a dual-stack socket sees an IPv4 client,
    counts as that IPv4 address too. A host that is not an address is not admitted.
    """
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        return False
    candidates = [address]
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped is not None:
        candidates.append(address.ipv4_mapped)
    return any(candidate in network for candidate in candidates for network in networks)


def loopback_only_warning(bound_host: str, allow_given: bool) -> str | None:
    """The warning for a site listening beyond loopback with the default allow-list; None otherwise.

    Such a site is reachable from the network but refuses every client not on
    its own machine: most likely a forgotten ``--allow``, said once at start
    rather than found at the first refusal.

    Parameters
    ----------
    bound_host : str
        The address the site listens on, as its socket reports it (``0.0.0.0``
        for every interface).
    allow_given : bool
        Whether ``--allow`` was given.
    """
    if allow_given or admits(LOOPBACK_NETWORKS, bound_host):
        return None
    return (
        f"warning: listening on {bound_host}, beyond loopback, but only loopback clients (127.0.0.0/8, ::1) "
        "will be accepted; give --allow ADDR or CIDR (e.g. --allow 192.168.10.0/24) to admit others"
    )
