"""Real hybrid tests: pendsweep as an experimental site and as a client of one.

OpenFresco's remote-test protocol over TCP (:mod:`.protocol`), spoken by
OpenSees's ``genericClient`` element:

* :mod:`.rig` and :mod:`.server`: ``pendsweep site`` serves the paper's
  physical substructure (the pendulum on its platform, behind a transfer
  system and sensors) to any client of the protocol;
* :mod:`.client`: the substructured backend's ``-B rig=tcp://HOST:PORT``
  sends its commands to a remote site instead of its virtual rig;
* :mod:`.log`: the site's log, one row per committed step.
"""

from .protocol import Action, ProtocolError, Setup, opensees_setup, parse_setup
from .rig import RigLimits, SiteRig, rig_from_options

__all__ = ["Action", "ProtocolError", "RigLimits", "Setup", "SiteRig", "opensees_setup", "parse_setup",
           "rig_from_options"]  # fmt: skip
