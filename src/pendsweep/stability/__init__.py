"""Stability of the substructured loop (section 2.4 of the paper and beyond).

- :mod:`._margins`: phase margins, stability switches and the critical delay
  of ``1 + F_s N_m e^{-s tau} = 0`` (Eqs. (8)-(9), Figs. 5-6, Table II);
- :mod:`._roots`: exact rightmost roots of the neutral DDE, Eq. (6);
"""

from ._margins import (
    Crossing,
    DelayMargin,
    delay_margin,
    gain_crossovers,
    loop_response,
    phase_margins,
    stability_chart,
    switch_sequence,
)
from ._roots import (
    characteristic,
    count_roots,
    critical_delay_from_roots,
    neutral_chain_abscissa,
    rightmost_roots,
    spectral_abscissa,
)

__all__ = [
    "Crossing",
    "DelayMargin",
    "characteristic",
    "count_roots",
    "critical_delay_from_roots",
    "delay_margin",
    "gain_crossovers",
    "loop_response",
    "neutral_chain_abscissa",
    "phase_margins",
    "rightmost_roots",
    "spectral_abscissa",
    "stability_chart",
    "switch_sequence",
]
