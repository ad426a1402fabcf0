"""Real hybrid tests: pendsweep as an experimental site and as a client of one.

OpenFresco's remote-test protocol over TCP (:mod:`.protocol`), spoken by
OpenSees's ``genericClient`` element:

* :mod:`.rig` and :mod:`.server`: ``pendsweep site`` serves the paper's
  physical substructure (the pendulum on its platform, behind a transfer
  system and sensors) to any client of the protocol;
* :mod:`.client`: the substructured backend's ``-B rig=tcp://HOST:PORT``
  sends its commands to a remote site instead of its virtual rig;
* :mod:`.connect`: ``tcp://HOST:PORT`` addresses and a connect that waits a
  bounded time for a site still starting (also ``pendsweep wait``);
* :mod:`.log`: the site's log, one row per committed step.

The package itself exports only the protocol: the backends import
:mod:`.client`, and :mod:`.rig` imports the backends, so importing the rig
here would close a circle.
"""

from .protocol import Action, ProtocolError, Setup, opensees_setup, parse_setup

__all__ = ["Action", "ProtocolError", "Setup", "opensees_setup", "parse_setup"]
