"""Whether GCS runs its compiled (numba) loops: one switch for the models, the batch, the
Kalman filter and the whole-span knots.

:data:`COMPILED` is True when numba imports and the environment variable
``GCS_NO_NUMBA`` is unset; every compiled loop then runs, otherwise its numpy form (the
same numbers to round-off; slower, and the path the tests check without numba). Compiled
functions are cached next to their module (``__pycache__``), so the compile (a few
seconds) is paid once per machine.
"""

from __future__ import annotations

import os
from types import ModuleType

numba: ModuleType | None
try:
    import numba
except ImportError:  # GCS works without it, slower
    numba = None

__all__ = ["COMPILED", "jit", "numba"]

#: the compiled loops are used (module docstring)
COMPILED = numba is not None and not os.environ.get("GCS_NO_NUMBA")


def jit(**options):
    """``numba.njit(cache=True, **options)`` when :data:`COMPILED`, else the identity."""
    if COMPILED:
        assert numba is not None  # COMPILED holds only when numba imported
        return numba.njit(cache=True, **options)
    return lambda fn: fn
