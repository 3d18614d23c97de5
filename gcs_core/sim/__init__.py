"""GCS truth simulator: independent physics that writes ICD mission directories.

Nothing here imports the estimator's models, ephemeris or rotation code
(``gcs_core.models``, ``gcs_core.ephem``, ``gcs_core.frames.rotations``): a bug shared by
the simulator and the estimator would cancel out and hide.

Modules: ``config`` (dataclasses), ``astro`` (GMST, Sun, shadow), ``orbit`` (secular-J2
orbit), ``field`` (IGRF), ``truth`` (attitude, rates, gyro, onboard attitude), ``sensors``
(TAM, FSS, CSS and the factory), ``stars`` (catalog, FHST), ``spinner`` (plane-field Sun
sensor, horizon scanner), ``aux`` (torquers, temperature), ``writer`` (ICD files and
truth.json), ``scenarios`` (named missions, hidden effects), ``samples`` (bundled data).

The data carry real always-on physics by default (stellar and solar aberration, solar
parallax, the WGS-84 horizon; ``MissionConfig.physics``); hidden effects (``with_effect``) are what the data
book does not say. ``list_effects()`` lists them with their units.

Typical use::

    from gcs_core.sim.scenarios import nominal_threeaxis, with_effect
    from gcs_core.sim.writer import write_mission
    cfg = with_effect(nominal_threeaxis("sun_pointing", seed=7), "TAM1.bias", 200.0)
    write_mission(cfg, "out/mission", truth_path="out/answers/mission.json")
"""
