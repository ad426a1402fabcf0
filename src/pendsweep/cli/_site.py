"""``pendsweep site``: serve the paper's physical substructure to OpenSees (or any OpenFresco-protocol client)."""

from __future__ import annotations

import click

from ._app import ANGLE, PATH, RATE, FiniteFloat, main
from ._checks import check_output, key_values, model_sets

TIMEOUT_S = FiniteFloat(1e-3, 3600.0, "s")


@main.command("site")
@click.option(
    "--port",
    type=click.IntRange(0, 65535),
    default=8090,
    show_default=True,
    help="TCP port to listen on; 0 picks a free one (printed on stderr).",
)
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="Address to listen on (loopback unless told otherwise; 0.0.0.0 for every interface, with --allow "
    "naming the clients).",
)
@click.option(
    "--allow",
    multiple=True,
    metavar="ADDR|CIDR[,...]",
    help="Client addresses that may drive the rig: IPv4 or IPv6 addresses or CIDR networks (e.g. 192.168.10.0/24), "
    "comma-separated or repeated. They replace the default, loopback only (127.0.0.0/8, ::1); any other client is "
    "closed at connect, before its set-up is read, with a line on stderr and in the log.",
)
@click.option("--once", is_flag=True, help="Serve one client, exit after its die message (status 0) or a fault (1).")
@click.option("-o", "--output", type=PATH, default=None, help="Log, one row per committed step (.parquet).")
@click.option("--theta0", type=ANGLE, default=0.1, show_default=True, help="Initial pendulum angle [rad].")
@click.option("--thetadot0", type=RATE, default=0.0, show_default=True, help="Initial pendulum rate [rad/s].")
@click.option(
    "--set",
    "sets",
    multiple=True,
    metavar="NAME=VALUE",
    help="Physical parameter of the rig, SI units (m, l, b1, b2, b3, g, M2, C2; fe for the load cell's harmonics).",
)
@click.option(
    "-B",
    "--backend-option",
    "rig_opts",
    multiple=True,
    metavar="KEY=VALUE",
    help="Rig option, as for --backend substructured: actuator (default ideal), transport_delay [s], "
    "servo_bandwidth [Hz], force_noise [N], lvdt_noise [m], encoder_resolution [rad], seed, stroke [m, 0.075]; "
    "and velocity_limit [m/s, 1.0], force_limit [N, 250], report_mass (true).",
)
@click.option("--realtime", is_flag=True, help="Pace each step to the wall clock and count deadline misses.")
@click.option(
    "--nudge",
    type=FiniteFloat(0.0, 1.0, "rad"),
    default=0.1,
    show_default=True,
    help="Angle [rad] (0 to 1) by which SIGUSR1 nudges the pendulum, the operator's hand (the paper's 0.1 rad "
    "perturbation; a client cannot give it through the protocol).",
)
@click.option(
    "--timeout",
    type=TIMEOUT_S,
    default=10.0,
    show_default=True,
    help="A client silent for longer [s] is a fault (0.001 to 3600).",
)
def site_command(port, host, allow, once, output, theta0, thetadot0, sets, rig_opts, realtime, nudge, timeout):
    """Serve the pendulum on its platform as an OpenFresco experimental site.

    Any client of OpenFresco's TCP protocol drives it: OpenSees's genericClient
    element, or `--backend substructured -B rig=tcp://HOST:PORT`. One client at
    a time, from an address --allow admits (default loopback only; a site
    listening beyond loopback without --allow warns so at start); each starts
    the rig from its initial state. A refused client is no session and never
    ends a --once site. Exit status with --once:
    0 when the client ended with die, 1 on a fault (the reason is on stderr and
    in the log's metadata); 2 for a bad command line. SIGINT or SIGTERM stop
    the site with its log written: status 0 between sessions, 1 mid-session.
    """
    import signal

    from ..hybrid.access import LOOPBACK_NETWORKS, loopback_only_warning, parse_allow
    from ..hybrid.log import SiteLog
    from ..hybrid.rig import rig_from_options
    from ..hybrid.server import SiteServer
    from ..model.params import ModelParams

    if output is not None:
        from ..engine.results import check_writable

        check_output(output, "-o/--output", (".parquet",))
        check_writable(output)  # before listening: a session must never be lost to an unwritable log
    allowed = parse_allow(allow) if allow else LOOPBACK_NETWORKS
    params = ModelParams.from_mapping(model_sets(sets))
    rig, config = rig_from_options(key_values(rig_opts, "-B"), params, theta0, thetadot0)
    config |= {
        "host": host,
        "allow": [str(network) for network in allowed],
        "port": port,
        "once": once,
        "realtime": realtime,
        "timeout_s": timeout,
    }
    log = SiteLog(output, config)
    import socket

    from ..errors import ConfigError, RunFailure

    try:
        server = SiteServer(
            rig, log, host=host, allow=allowed, port=port, once=once, timeout=timeout, realtime=realtime
        )
    except OSError as exc:
        if isinstance(exc, socket.gaierror) or (exc.errno or 0) < 0:  # not an address (getaddrinfo's codes are < 0)
            raise ConfigError(f"--host {host!r} is not an address to listen on ({exc.strerror or exc})") from None
        raise RunFailure(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None  # e.g. a port in use

    warning = loopback_only_warning(server.address[0], allow_given=bool(allow))  # the bound address, not a name
    if warning:
        click.echo(f"pendsweep site: {warning}", err=True)

    def stop(signum, frame):
        raise KeyboardInterrupt

    def nudged(signum, frame):
        rig.request_nudge(nudge)
        click.echo(f"pendsweep site: the pendulum is nudged by {nudge:g} rad (SIGUSR1)", err=True)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGUSR1, nudged)
    try:
        status = server.serve()
    except KeyboardInterrupt:
        cut = bool(server.sessions) and server.sessions[-1].interrupted
        written = "; log written" if output is not None else ""
        click.echo(f"pendsweep site: stopped by a signal{' mid-session' if cut else ''}{written}", err=True)
        status = 1 if cut else 0
    if status:
        raise SystemExit(status)
