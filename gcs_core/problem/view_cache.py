"""A cache of what is computed from times that view a longer array.

The linearization passes ask the same questions of the same frame times at every pass: where
a chunk of a sensor's times falls among the gyro's knots
(:meth:`~gcs_core.problem.gyro_attitude.GyroAttitude._locate`), or among the read-out
errors' epochs (:meth:`~gcs_core.estimators.whole_span.epoch_errors.EpochErrors._locate`).
The answers depend on the times alone, and a chunk is a view of the sensor's time array, so
they are kept under the view's place: the viewed array's identity, the view's offset, size
and end values (frame times are never changed in place) and the caller's own tag. A weak
reference ties each entry to the viewed array, so an entry neither keeps it alive nor
answers for another array later given its address.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Hashable
from typing import Any

import numpy as np


class ViewCache:
    """Values computed from 1-D views of longer arrays (module docstring), at most ``limit``
    entries (a long span's chunks; all are dropped when it is reached)."""

    def __init__(self, limit: int):
        self.limit = limit
        self._entries: dict[tuple, tuple[weakref.ref, Any]] = {}

    def get(self, src: np.ndarray, tag: Hashable, compute: Callable[[], Any]) -> Any:
        """The value for the times ``src`` and ``tag``: kept when ``src`` views a longer
        1-D array with its strides, else computed each time."""
        base = src.base if isinstance(src.base, np.ndarray) and src.base.ndim == 1 else None
        if base is None or src.ndim != 1 or not src.size or src.strides != base.strides:
            return compute()
        off = (src.__array_interface__["data"][0] - base.__array_interface__["data"][0]) // src.itemsize
        key = (id(base), int(off), src.size, float(src[0]), float(src[-1]), tag)
        held = self._entries.get(key)
        if held is not None and held[0]() is base:
            return held[1]
        value = compute()
        if len(self._entries) >= self.limit:
            self._entries.clear()
        self._entries[key] = (weakref.ref(base), value)
        return value
