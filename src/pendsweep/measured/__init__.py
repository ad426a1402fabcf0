"""Learning from data: measured records, a hybrid test's own logs, and the diagnosis.

Layer 6, beside :mod:`pendsweep.studies` (independent of it):

* :mod:`.records`: the measured-data format (reader, writer, validation);
* :mod:`.logs`: a site log or substructured trace read as records;
* :mod:`.diagnose`: what a simulation gets wrong against records, as one
  pipeline (identify, replay, fit, judge, report).
"""
