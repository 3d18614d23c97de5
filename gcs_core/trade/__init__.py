"""Plan before launch (seed §1.1): trade studies, a plan optimizer and Monte Carlo.

- :mod:`.space` — the keys a study varies and how each changes a plan;
- :mod:`.study` — :class:`StudyDefinition`, the predictor per plan, ranking;
- :mod:`.run` — :func:`run_study`: a study to its HDF5 results file, resumable;
- :mod:`.optimize` — the cheapest plan meeting σ targets within a budget;
- :mod:`.montecarlo` — simulate and fit a plan many times, scatter against predicted σ;
- :mod:`.engine` — serial or Dask execution; :mod:`.store` — the results files.

Nothing here imports Dask unless ``workers`` or ``scheduler`` is given.
"""
