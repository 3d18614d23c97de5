"""The calibration problem every estimator reads (seed §3.2.2: SODL and SIDP).

* :mod:`~gcs_core.problem.state` — the state vector by name, and the element roles
  (solve-for, consider, held; Table 3-1);
* :mod:`~gcs_core.problem.prepare` — geometry and data preparation: reference vectors
  (Sun, field, ephemeris) at the sensors' frames, the physics options;
* :mod:`~gcs_core.problem.attitude` — the attitude providers behind one
  :class:`~gcs_core.problem.attitude.AttitudeProvider` protocol (Eq 4-2, 4-4..4-7),
  with the gyro-carried attitude in :mod:`~gcs_core.problem.gyro_attitude`
  (Eq 4-32, 4-33, 4-38) and its compiled loops in :mod:`~gcs_core.problem.kernels`;
* :mod:`~gcs_core.problem.build` — :func:`~gcs_core.problem.build.build_problem`: choosing
  the models defines the state (Table 3-1);
* :mod:`~gcs_core.problem.linearization` — residuals ``r = y − h(x)`` and partials
  ``H = ∂h/∂x`` of every sensor, block by block; :mod:`~gcs_core.problem.curvature` —
  the residual-weighted second partials.

Nothing here imports an estimator, the predictor, the diagnosis or a report.
"""
