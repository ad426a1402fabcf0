"""Stability of the substructured loop (section 2.4 of the paper and beyond).

- :mod:`._margins`: phase margins, stability switches and the critical delay
  of ``1 + F_s N_m e^{-s tau} = 0`` (Eqs. (8)-(9), Figs. 5-6, Table II);
- :mod:`._roots`: exact rightmost roots of the neutral DDE, Eq. (6);
- :mod:`._sampled`: the loop exactly as the substructured backend runs it
  (sampled data, servo or delay actuator, predictor, force filter);
- :mod:`._simulate`: the critical delay measured on the backend;
- :mod:`._report`: Table II and the margin table as text.
"""

from ._margins import (
    Crossing,
    DelayMargin,
    delay_margin,
    gain_crossovers,
    loop_response,
    numeric_crossings,
    phase_margins,
    servo_delay_margin,
    servo_response,
    stability_chart,
    switch_sequence,
)
from ._report import format_crossings, format_table_ii, table_ii
from ._roots import (
    characteristic,
    count_roots,
    critical_delay_from_roots,
    neutral_chain_abscissa,
    rightmost_roots,
    spectral_abscissa,
)
from ._sampled import SampledLoop, SampledMargin, multipliers, open_loop, sampled_delay_margin, sampled_response
from ._simulate import Growth, SimulatedMargin, simulated_delay_margin, simulated_growth

__all__ = [
    "Crossing",
    "DelayMargin",
    "Growth",
    "SampledLoop",
    "SampledMargin",
    "SimulatedMargin",
    "format_crossings",
    "format_table_ii",
    "multipliers",
    "numeric_crossings",
    "open_loop",
    "sampled_delay_margin",
    "sampled_response",
    "servo_delay_margin",
    "servo_response",
    "simulated_delay_margin",
    "simulated_growth",
    "table_ii",
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
