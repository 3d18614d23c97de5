"""Cooperative cancellation of long engine work (a fit, a ranking) from another thread.

A face runs engine work inside :func:`cancellable` with a predicate (the TUI: "has the
user pressed esc or q?"); the engine calls :func:`checkpoint` at points where stopping
loses nothing — every chunk of every linearization, so every iteration of every
estimator and every ranking pass meets one within a fraction of a second — and
:class:`Cancelled` unwinds the work. Outside :func:`cancellable` a checkpoint costs one
attribute lookup and never raises (headless runs, tests).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from gcs_core.errors import GcsError

_local = threading.local()


class Cancelled(GcsError):
    """The work was cancelled at a checkpoint (nothing was half-written)."""


@contextmanager
def cancellable(cancelled: Callable[[], bool] | None) -> Iterator[None]:
    """Within the block, :func:`checkpoint` raises :class:`Cancelled` once ``cancelled()``
    is True (this thread only; nests: the inner predicate wins while it runs)."""
    previous = getattr(_local, "cancelled", None)
    _local.cancelled = cancelled
    try:
        yield
    finally:
        _local.cancelled = previous


def checkpoint() -> None:
    """Raise :class:`Cancelled` when the work running on this thread was cancelled."""
    cancelled = getattr(_local, "cancelled", None)
    if cancelled is not None and cancelled():
        raise Cancelled("cancelled")
