"""Hybrid testing: pendsweep as an experimental site, as a client of one, and the accuracy of a test.

Layer 5, above the analyses (a site log is classified), below the studies.

OpenFresco's remote-test protocol over TCP (:mod:`.protocol`), spoken by
OpenSees's ``genericClient`` element:

* :mod:`.rig` and :mod:`.server`: ``pendsweep site`` serves the paper's
  physical substructure (the pendulum on its platform, behind a transfer
  system and sensors) to any client of the protocol;
* :mod:`.client`: the substructured backend's ``-B rig=tcp://HOST:PORT``
  sends its commands to a remote site instead of its virtual rig;
* :mod:`.connect`: ``tcp://HOST:PORT`` addresses and a connect that waits a
  bounded time for a site still starting (also ``pendsweep wait``);
* :mod:`.log`, :mod:`.log_rows`: the site's log, one row per committed step;
* :mod:`.session`: one continuous test through one connection;
* :mod:`.trace` and :mod:`.sync`: a substructured run's trace and its
  synchronisation accuracy (section 4).

The backends never import this package: a remote rig reaches the
substructured backend as a transport it is handed
(:class:`pendsweep.backends.substructured.RigTransport`,
:data:`.client.TCP_TRANSPORT`). The package itself exports only the protocol,
so importing it stays light.
"""

from .protocol import Action, ProtocolError, Setup, opensees_setup, parse_setup

__all__ = ["Action", "ProtocolError", "Setup", "opensees_setup", "parse_setup"]


def __getattr__(name: str):
    """0.1's ``pendsweep.hybrid`` module held the trace functions: they stay here for one release."""
    if name in ("run_trace", "write_trace", "read_trace"):
        import warnings

        from . import trace

        warnings.warn(f"pendsweep.hybrid.{name} moved to pendsweep.hybrid.trace.{name}", DeprecationWarning, 2)
        globals()[name] = getattr(trace, name)  # warned once: `from ... import` looks a name up twice
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
