"""The studies users run: sweeps, maps, basins, Hopf-boundary scans, a sweep on a real rig.

Layer 6, above analyses and hybrid testing; beside :mod:`pendsweep.measured`,
which it does not import (nor it this):

* :mod:`.sweep`, :mod:`.sweep_rows`, :mod:`.sweepfile`: bifurcation sweeps
  (``pendsweep alpha``, ``pendsweep run fig11a``);
* :mod:`.rig_sweep`: one sweep as one continuous test on a remote rig;
* :mod:`.basins`, :mod:`.maps`: basins of attraction and parameter maps;
* :mod:`.hopf`: Hopf-boundary grid scans over (alpha, omega-hat, M).
"""
