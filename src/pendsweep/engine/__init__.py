"""The run engine: plan work, run it anywhere, keep every finished unit.

Layer 3, above :mod:`pendsweep.backends` (a scan runs points on one):

* :mod:`.scan`: a study as units of work, resumable, with progress;
* :mod:`.executors`: this process or a Dask cluster;
* :mod:`.results`, :mod:`.merge`, :mod:`.columns`, :mod:`.output_lock`:
  crash-safe parquet parts, their merge, metadata, one writer per output.

It knows no analysis and no study: what a unit computes is handed in.
"""
