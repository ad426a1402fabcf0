"""Analyses of one system at one parameter, or along one branch.

Layer 4, above the run engine (continuation writes resumable files with it):

* :mod:`.classify`, :mod:`.sections`, :mod:`.attractors`: what motion a
  record shows (stroboscopic sections, periods, rotations, chaos);
* :mod:`.semi_trivial`, :mod:`.hopf_protocol`: the semi-trivial solution,
  its Floquet multipliers and the simulated Hopf point;
* :mod:`.stability`: phase and delay margins of the substructured loop;
* :mod:`.continuation`: periodic orbits continued in one or two parameters.
"""
