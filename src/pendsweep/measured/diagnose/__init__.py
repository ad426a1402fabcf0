"""Learn from measured data: where the model disagrees, which effect explains it,
the extended model and its gain on held-out data."""

from .effects import EFFECTS, Effect, applicable
from .fit import Diagnosis, diagnose
from .fitting import Fit, Problem, fit_model
from .replay import Replay
from .synth import Sensors, synthesize

__all__ = [
    "EFFECTS",
    "Diagnosis",
    "Effect",
    "Fit",
    "Problem",
    "Replay",
    "Sensors",
    "applicable",
    "diagnose",
    "fit_model",
    "synthesize",
]
