"""Observation models of the seven sensor types (seed §4.2, ICD §5).

:data:`MODEL_TYPES` maps each ICD type key to its model class; :func:`make_model` builds
the model of one configured sensor. The contract is in :mod:`gcs_core.models.base`,
the shared partial-derivative checker in :mod:`gcs_core.models.checks`.
"""

from __future__ import annotations

from gcs_core.errors import InputError
from gcs_core.io.types import SensorSpec
from gcs_core.models.attitude_reference import AttitudeReferenceModel
from gcs_core.models.base import ObservationModel
from gcs_core.models.coarse_sun import CoarseSunModel
from gcs_core.models.fine_sun import FineSunModel
from gcs_core.models.gyro import GyroModel
from gcs_core.models.horizon import HorizonModel
from gcs_core.models.magnetometer import MagnetometerModel
from gcs_core.models.plane_field_sun import PlaneFieldSunModel
from gcs_core.models.star_tracker import StarTrackerModel

__all__ = ["MODEL_TYPES", "make_model"]

#: ICD §5 type key -> model class.
MODEL_TYPES: dict[str, type[ObservationModel]] = {
    cls.type_name: cls
    for cls in (
        MagnetometerModel,
        GyroModel,
        StarTrackerModel,
        FineSunModel,
        CoarseSunModel,
        PlaneFieldSunModel,
        HorizonModel,
        AttitudeReferenceModel,
    )
}


def make_model(
    sensor: SensorSpec, *, aux_channels: tuple[str, ...] = (), constant_field: bool = False
) -> ObservationModel:
    """The observation model of ``sensor``; ``aux_channels`` feed the magnetometer's
    contamination parameters (ignored by the other types); ``constant_field`` gives a
    magnetometer the unknown constant reference field ``field.B_x/y/z`` (physics
    ``field_model = "constant"``, docs/ground.md).

    Raises :class:`~gcs_core.errors.InputError` naming the type key if it is unknown.
    """
    cls = MODEL_TYPES.get(sensor.type)
    if cls is None:
        raise InputError(
            f"sensor '{sensor.name}' has unknown type '{sensor.type}' (known: {', '.join(MODEL_TYPES)})",
            key=f"{sensor.name}.type",
        )
    if constant_field and cls is MagnetometerModel:
        return cls(sensor, aux_channels=tuple(aux_channels), constant_field=True)
    return cls(sensor, aux_channels=tuple(aux_channels))
