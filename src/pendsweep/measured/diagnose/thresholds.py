"""The diagnosis's decision thresholds, each chosen on the calibration seeds of :mod:`pendsweep.measured.diagnose.testbench` only."""

from __future__ import annotations

import math

FLOOR_SHARE = 0.25
SHARE_MIN = 0.5
SECOND_SHARE_MIN = 0.5
P_VALUE = 1e-3
Z_MIN = 4.0
#: A resting pendulum's encoder zero is known to within half an encoder step, uniformly (one-sigma
#: step / sqrt(12)): a change beyond that half step, z >= sqrt(3), is certain, where Z_MIN, made
#: for Gaussian errors, would discard a one-step reading.
Z_BOUNDED = math.sqrt(3.0)
#: The second round runs when the best single cause leaves more than this multiple of the floor^2.
SECOND_ROUND_RATIO = 2.0
#: The second cause is sought among this many next-best single causes.
PARTNERS = 3
#: Second rounds start from this many best single causes.
BEAM = 2
#: Cross-validated squared error above this multiple of the floor^2 is "unexplained" (per kind). Forced
#: records: 4.5, 1.6 x the largest ratio (2.8) of the clean and correctly named single-effect and pair
#: records of calibration range A since each segment's start and LVDT offset are fitted with the model
#: (issue 34); it was 30 while the smoothed starts left the true model at up to 20 x the floor^2.
UNEXPLAINED_RATIO = {"free_decay": 3.0, "forced": 4.5, "substructured": 4.5, "physical": 4.5, "numerical": 4.5}
#: One sensor channel's cross-validated mean square above this multiple of its own noise variance
#: is a structured residual too (kinds whose pooled floor one noisy channel dominates).
CHANNEL_RATIO = {"substructured": 60.0, "physical": 120.0}
#: An estimate more than this factor from its nonzero nominal is physically implausible: the cause
#: is not named (its parameter is absorbing something else). The identifiable ranges are 1.03-8 x
#: nominal; on the calibration range A the largest ratio of any best or runner-up single cause was
#: 8.2 (of any pair's 32), on the three real records 76 (b3); a resting pendulum's encoder zero,
#: before its constant angle was compared, was absorbed by b3 at 2.8e5 x nominal.
IMPLAUSIBLE_FACTOR = 1000.0
#: Factor from a fit's own one-sigma uncertainty (Jacobian, raised to the fold jackknife; what the
#: tests use) to the stated one, by record kind. On the calibration range A (49 right single
#: verdicts) the median |estimate - truth| / sigma was 1.23 (free decay), 2.32 (forced) and 0.44
#: (substructured); each factor brings it to 0.674, the median |z| of a normal error, and none is
#: below 1 (the substructured jackknife is already wide). Forced records recalibrated with the
#: segment starts fitted (issue 34): median 1.41 on the 16 right forced singles, factor 2.10 (was
#: 3.44). Held-out check: the diagnosis benchmark's ``uncertainty_coverage`` on range B.
UNCERTAINTY_CALIBRATION = {"free_decay": 1.83, "forced": 2.10, "substructured": 1.0, "physical": 1.0, "numerical": 1.0}
#: Smallest relative change of a parameter that is named, per record kind: below it a significant
#: change is the model-form error of a rig's conventions, not a fault. The physical part's platform
#: mass: on the calibration range A, a command held over each tick into a first-order servo made the
#: tick-synchronous load cell read the platform 3.8 to 4.5 % heavy or light (3 of 160 records, each a
#: spurious second cause); the benchmark's platform-mass effects are 30 % and more.
#: The numerical part's output is exact, so any controller convention this replay does not model (a
#: forward predictor whose amplitude is off by a few per cent, a y* logged a tick apart) is a
#: significant change of some parameter: changes below these are not named. Set after an independent
#: check's servo rigs (a linear least-squares predictor read as a 2.4-2.7 % forcing gain; a one-tick
#: tag of y* as a 0.05 % mass; a Newmark controller as a 0.4 % damping), so those records no longer
#: test them; the benchmark's effects are 4 % (K) to 20 % (C) and more.
RELEVANCE = {"physical": {"M2": 0.10}, "numerical": {"M": 0.02, "K": 0.02, "C": 0.05, "gain": 0.04}}
#: A measured platform velocity or acceleration (``ydot``, ``yddot``) whose mean-square difference from the
#: motion that drives the specimen's replay exceeds this multiple of its noise variance flags the record
#: (the specimen was replayed under a motion the rig did not make). The physical part's channel ratio:
#: the same test of a structured residual against a sensor's own noise.
DERIVATIVE_RATIO = CHANNEL_RATIO["physical"]
