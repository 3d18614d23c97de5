"""A fleet's daily calibration: many spacecraft, one manifest, tasks on Dask (docs/fleet.md).

Modules:

* :mod:`~gcs_core.fleet.manifest` — the fleet manifest (TOML): spacecraft, where each one's
  data come from, the analysis-config template and each spacecraft's overrides;
* :mod:`~gcs_core.fleet.task` — what one worker computes for one spacecraft-day (fit,
  goodness of fit, verification, optional discovery) from data it is handed, never from a
  path of the submitting machine;
* :mod:`~gcs_core.fleet.store` — each spacecraft's SCDS and ASF, the content hash of a
  day's inputs and config, what is already done;
* :mod:`~gcs_core.fleet.run` — the submitter: reads the missions, ships them to the
  workers (a ``LocalCluster`` on 127.0.0.1 or a given scheduler), appends the results;
* :mod:`~gcs_core.fleet.report` and :mod:`~gcs_core.fleet.html` — the fleet report, JSON
  and one self-contained HTML page;
* :mod:`~gcs_core.fleet.ccsds` — the calibrated attitude history out as a CCSDS AEM (an
  OEM as a mission's ephemeris is read by :mod:`gcs_core.io.ccsds`);
* :mod:`~gcs_core.fleet.simulate` — a simulated fleet (gcs_core.sim) for tests and
  benchmarks.
"""
