"""The predictor (seed §3.1, §3.2): attitude and sensor-bias accuracies without data.

- :mod:`.plan` — :class:`DataPlan`, the data modeling of seed §4.3 (segments, gaps,
  maneuvers Eq 4-35/4-36, cadences).
- :mod:`.nominal` — nominal attitude, sensor availability.
- :mod:`.stars` — star-tracker headers: the star models ``catalog`` (a catalog file),
  ``telemetry`` (the stars the trackers identified), ``sky`` (synthetic) and ``uniform``.
- :mod:`.synth` — the calibration Problem built from frame times only (SDF headers).
- :mod:`.information` — Eq 3-2 accumulation and the consider budget.
- :mod:`.kalman` — the covariance-only recursion of Eq 3-4.
- :mod:`.predict` — :func:`predict` and :class:`PredictionResult`.
"""
