"""Auxiliary channels at given times (ICD §6: each channel holds its value until its next
row): read by the problem's preparation and by the models that need a channel at the gyro's
rows (:mod:`gcs_core.models.gyro_steps`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from gcs_core.io.types import Table


def hold_channels(aux: Table | None, t: np.ndarray) -> dict[str, np.ndarray]:
    """ICD §6: each auxiliary channel holds its value until its next row.

    Frames before the first aux row take the first row's value.
    """
    if aux is None or len(aux) == 0:
        return {}
    k = np.clip(np.searchsorted(aux.t, t, side="right") - 1, 0, len(aux) - 1)
    return {name: np.asarray(col)[k] for name, col in aux.columns.items() if name != "t"}


def aux_channel_names(aux: Table | None) -> tuple[str, ...]:
    return tuple(n for n in aux.columns if n != "t") if aux is not None else ()
