"""``pendsweep wait``: block until a site listens, for clients that connect once (OpenSees)."""

from __future__ import annotations

import click

from ._app import FiniteFloat, main


@main.command("wait")
@click.argument("url", metavar="tcp://HOST:PORT")
@click.option(
    "--timeout",
    type=FiniteFloat(0.0, 3600.0, "s"),
    default=10.0,
    show_default=True,
    help="Give up after this long [s] (0 to 3600): exit status 1 with one line.",
)
def wait_command(url, timeout):
    """Wait until something listens at tcp://HOST:PORT, then exit 0.

    `pendsweep site ... &` takes about 2 s before it listens; OpenSees's
    genericClient tries to connect once and fails at once. Put this line
    between the two. It connects and closes without a word, which a site
    does not count as a client (even with --once). pendsweep's own client
    (-B rig=tcp://...) waits by itself, up to 10 s.
    """
    from ..errors import ConfigError
    from ..hybrid.connect import connect, parse_rig_url

    try:
        host, port = parse_rig_url(url)
    except ConfigError:
        raise ConfigError(f"URL {url!r}; give tcp://HOST:PORT (e.g. tcp://127.0.0.1:8090)") from None
    # one try may take as long as the whole wait (a host that drops the connection), never longer
    connect(host, port, timeout=max(timeout, 0.1), deadline=timeout, what="a site").close()
