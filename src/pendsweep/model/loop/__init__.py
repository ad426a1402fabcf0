"""The substructuring loop's transfer-system pieces, shared by every model of the loop.

One implementation each of the actuator delay (:mod:`.delay`), the
polynomial forward predictor (:mod:`.predictor`) and the force filter
(:mod:`.filter`), used by the substructured backend, the exact sampled-loop
stability model (:mod:`pendsweep.analysis.stability`) and the synthetic records of
the diagnosis. One meaning for every option:

* ``tau_hat``, the prediction horizon [s]: a number, or ``None`` for
  *matched*, the total effective delay of the transfer system at the design
  frequency (:func:`~.delay.prediction_horizon`).
"""

from .delay import ACTUATORS, effective_delay, phase_to_delay, prediction_horizon
from .filter import design_force_filter, filter_delay, filter_phase
from .predictor import MAX_PREDICTOR_ORDER, predictor_weights

__all__ = [
    "ACTUATORS",
    "MAX_PREDICTOR_ORDER",
    "design_force_filter",
    "effective_delay",
    "filter_delay",
    "filter_phase",
    "phase_to_delay",
    "prediction_horizon",
    "predictor_weights",
]
