"""The gyro's bias following aux channels: a generic family carried inside the attitude.

A gyro has no residuals of its own when it carries the attitude (seed §4.2.7): its rates
drive the propagation. A bias that steps when a heater switches,

    b(t) = b + ḃ τ + k x(t)                                   (x: the heater channel),

therefore shows in the other sensors' residuals as an attitude error growing with
``∫ k x dt`` (the time integral of the channel, :mod:`gcs_core.diagnosis.channels`), and
the family ``bias_vs_<channel>`` lives in the gyro-carried attitude
(:class:`~gcs_core.problem.gyro_attitude.GyroAttitude`, its ``steps``), where its partials
are the cumulative sums of the bias's with ``x`` in place of ``τ``. This module names the
family's elements on the gyro's model (:class:`GyroStepModel`) and forms the channels at
the gyro's rows (:func:`step_channels`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from gcs_core.models.base import ObservationModel, ParamSpec
from gcs_core.models.drift import split_family
from gcs_core.models.gyro import AXES, GyroModel

#: a-priori 1-sigma of a bias step per unit of the channel [rad/s]: 1 °/h, far above any heater's
STEP_SIGMA = np.radians(1.0) / 3600.0


def step_tags(families: Iterable[str], aux_names: Iterable[str]) -> tuple[str, ...]:
    """The aux channels of the gyro's ``bias_vs_<channel>`` families (others are ignored)."""
    names = set(aux_names)
    out = []
    for fam in families:
        parts = split_family(fam)
        if parts is not None and parts[0] == "bias" and parts[1] in names and parts[1] not in out:
            out.append(parts[1])
    return tuple(out)


def step_channels(t_rows: np.ndarray, aux, tags: Sequence[str]) -> dict[str, np.ndarray]:
    """channel -> (K,) its value over each gyro row's interval ``(t_{k−1}, t_k]``: held
    (ICD §6) at the interval's middle, the first interval as long as the median one."""
    from gcs_core.io.aux_hold import hold_channels

    t = np.asarray(t_rows, float)
    if not tags or t.size == 0:
        return {}
    dt = np.diff(t)
    first = float(np.median(dt)) if dt.size else 1.0
    mid = t - 0.5 * np.concatenate([[first], dt])
    held = hold_channels(aux, mid)
    return {tag: np.asarray(held[tag], float) for tag in tags}


class GyroStepModel(GyroModel):
    """The gyro's model with the elements of its ``bias_vs_<channel>`` families
    (``bias_x_vs_<channel>`` ... [rad/s per unit of the channel], effect ``bias_vs_<channel>``,
    held by default: candidates). The propagation carries them (module docstring); as an
    observation model (a gyro not carrying the attitude) they are not offered."""

    def __init__(self, inner: ObservationModel, tags: Sequence[str]):
        super().__init__(inner.sensor, aux_channels=inner.aux_channels)
        self.step_tags = tuple(tags)

    def parameters(self) -> tuple[ParamSpec, ...]:
        extra = tuple(
            ParamSpec(
                f"bias_{ax}_vs_{tag}",
                f"rad/s per unit of {tag}",
                0.0,
                STEP_SIGMA,
                seed=False,
                effect=f"bias_vs_{tag}",
                description=f"drift-rate bias about sensor {ax} per unit of {tag} (carried in the attitude)",
            )
            for tag in self.step_tags
            for ax in AXES
        )
        return super().parameters() + extra


def with_steps(model: ObservationModel, families: Sequence[str], aux_names: Iterable[str]) -> ObservationModel:
    """``model`` (a gyro's) with its step families, or unchanged without any."""
    tags = step_tags(families, aux_names)
    if not tags or not isinstance(model, GyroModel):
        return model
    return GyroStepModel(model, tags)


def gyro_step_channels(
    families: Mapping[str, Sequence[str]] | None, gyro: str, t_rows: np.ndarray, aux
) -> dict[str, np.ndarray]:
    """channel -> (K,) at the gyro's rows, for the ``bias_vs_<channel>`` families named for
    ``gyro`` among ``families`` (sensor -> family effects) whose channel ``aux`` has."""
    from gcs_core.io.aux_hold import aux_channel_names

    tags = step_tags((families or {}).get(gyro, ()), aux_channel_names(aux))
    return step_channels(t_rows, aux, tags)
