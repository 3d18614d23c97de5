"""VERIF (seed §3.2.2, §4.4): onboard attitudes against the ground attitude.

- :mod:`.compare` — :func:`verify`, :class:`VerifResult`, the §4.4 statistic and flag rule.
- :mod:`.ground` — the fitted attitude with its 1-σ.
- :mod:`.analysis` — :func:`verify_analysis` on a fitted :class:`~gcs_core.session.Analysis`.
"""
