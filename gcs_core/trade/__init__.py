"""Plan before launch (seed §1.1): trade studies, a plan optimizer and Monte Carlo.

- :mod:`.space` — the keys a study varies and how each changes a plan;
- :mod:`.study` — :class:`StudyDefinition`, the predictor per plan, ranking;
- :mod:`.run` — :func:`run_study`: a study to its HDF5 results file, resumable;
- :mod:`.optimize` — the cheapest plan meeting σ targets within a budget;
  :mod:`.robustness` — how much it depends on the start phase it did not control;
- :mod:`.montecarlo` — simulate and fit a plan many times, scatter against predicted σ;
- :mod:`.engine` — serial or Dask execution; :mod:`.store` — the results files.

Every command reads the plan once through :mod:`gcs_core.predictor.source` (one code path,
one orbit, one estimator: ``whole_span`` unless the config says otherwise; docs/planning.md).
Nothing here imports Dask unless ``workers`` or ``scheduler`` is given.

The analysis config's planning tables (:mod:`gcs_core.config` reads them with the rest)::

    [trade]                       # gcs trade / gcs optimize (gcs_core/trade)
    targets = ["TAM1.bias", "FHST1.misalignment", "attitude"]
    output = "trade.h5"           # results file, relative to this config
    top = 3                       # error budgets printed for the best plans
    [trade.vary]                  # keys of gcs_core.trade.space and their values
    span_min = [10, 20, 48, 95]
    "models.FHST2" = ["on", "off"]
    [trade.orbit]                 # Kepler elements: every plan's ephemeris (any span or start)
    a_km = 6898.137
    e = 0.0012
    i_deg = 28.5
    raan_deg = 35.0
    argp_deg = 60.0
    mean_anomaly_deg = 10.0
    [trade.optimize]
    targets = ["TAM1.alignment<0.01deg", "FHST1.misalignment<10arcsec"]
    budget = {slew_min = 10.0, hours = 2.0, axes = ["roll", "yaw"], rates = [0.1], passes = [1, 2]}

    [montecarlo]                  # gcs montecarlo
    runs = 100
    seed = 20261202               # entropy of the SeedSequence
    output = "montecarlo.h5"
"""
