"""Learn from measured data: where the model disagrees, which effect explains it,
the extended model and its gain on held-out data.

The diagnosis is one pipeline (:mod:`.pipeline`): identify, replay, fit, judge,
report, one module or sub-package per stage. The effect vocabulary
(:mod:`.effects`), signal helpers (:mod:`.signals`) and residual features
(:mod:`.signatures`) serve several stages; the free-swing damping fit
(:mod:`.damping`) is an appendix; :mod:`.synth`, :mod:`.testbench`,
:mod:`.servo_rig` and :mod:`.populations` generate records to test it on.
"""

from .effects import EFFECTS, Effect, applicable
from .fit import Fit, Problem, fit_model
from .judge import Diagnosis, PartsDiagnosis
from .pipeline import diagnose, diagnose_parts, diagnose_records
from .replay import Replay
from .synth import Sensors, synthesize

__all__ = [
    "EFFECTS",
    "Diagnosis",
    "Effect",
    "Fit",
    "PartsDiagnosis",
    "Problem",
    "Replay",
    "Sensors",
    "applicable",
    "diagnose",
    "diagnose_parts",
    "diagnose_records",
    "fit_model",
    "synthesize",
]
