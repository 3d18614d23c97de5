"""Whether GCS runs its compiled (numba) loops: one switch for the models, the batch, the
Kalman filter and the whole-span knots.

:data:`COMPILED` is True when numba imports and the environment variable
``GCS_NO_NUMBA`` is unset; every compiled loop then runs, otherwise its numpy form (the
same numbers to round-off; slower, and the path the tests check without numba). Compiled
functions are cached next to their module (``__pycache__``), so the compile (a few
seconds) is paid once per machine; :func:`cache_choice` falls back when that folder and
the user's cache folder cannot be written.
"""

from __future__ import annotations

import os
import stat
import tempfile
from types import ModuleType


def _writable(folder: str) -> bool:
    """A file can be created in ``folder`` (created if missing): tried, not guessed."""
    from gcs_core.fileperm import probe_folder

    try:
        os.makedirs(folder, exist_ok=True)
        probe_folder(folder)
    except OSError:
        return False
    return True


def _private_dir(folder: str) -> bool:
    """``folder`` exists (made here if missing), is ours and writable by us alone."""
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        st = os.lstat(folder)
    except OSError:
        return False
    return stat.S_ISDIR(st.st_mode) and st.st_uid == os.getuid() and not st.st_mode & 0o022


def cache_choice() -> tuple[bool, str | None]:
    """(cache the compiled loops, NUMBA_CACHE_DIR to set or None).

    numba caches beside the module (``__pycache__``), else in the user's cache folder.
    On a read-only install with an unwritable HOME neither works and ``cache=True`` fails
    at import ("no locator available"); GCS then caches in a private folder of the
    temporary directory (``gcs-numba-<uid>``, refused unless ours and 0700), or, failing
    that, compiles without caching (each run pays the compile once).
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return True, None
    here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "__pycache__")
    user = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "numba")
    if _writable(here) or _writable(user):
        return True, None
    fallback = os.path.join(tempfile.gettempdir(), f"gcs-numba-{os.getuid()}")
    if _private_dir(fallback) and _writable(fallback):
        return True, fallback
    return False, None


CACHE, _cache_dir = cache_choice()
if _cache_dir is not None:
    os.environ["NUMBA_CACHE_DIR"] = _cache_dir  # before numba reads its configuration

numba: ModuleType | None
try:
    import numba
except ImportError:  # GCS works without it, slower
    numba = None

__all__ = ["CACHE", "COMPILED", "cache_choice", "jit", "numba"]

#: the compiled loops are used (module docstring)
COMPILED = numba is not None and not os.environ.get("GCS_NO_NUMBA")


def jit(**options):
    """``numba.njit(cache=CACHE, **options)`` when :data:`COMPILED`, else the identity
    (:func:`cache_choice`: caching falls back when no cache folder can be written)."""
    if COMPILED:
        assert numba is not None  # COMPILED holds only when numba imported
        return numba.njit(cache=CACHE, **options)
    return lambda fn: fn
