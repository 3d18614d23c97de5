"""The permissions of the files GCS writes.

Atomic writes go through ``tempfile.mkstemp``, which creates files readable by their
owner only (0600). Reports, configs, plots and data sets are not secrets: they get the
mode an ordinary ``open(..., "w")`` would give, 0666 less the process umask (0644 with
the usual umask 022), the same as the HDF5 files h5py creates.
"""

from __future__ import annotations

import os
import threading

_lock = threading.Lock()


def usual_mode() -> int:
    """0666 less the current umask (read without changing it for other threads for long)."""
    with _lock:
        mask = os.umask(0o022)
        os.umask(mask)
    return 0o666 & ~mask


def make_usual(fd_or_path) -> None:
    """Give a file just written through ``mkstemp`` the usual permissions (module docstring)."""
    mode = usual_mode()
    if isinstance(fd_or_path, int):
        os.fchmod(fd_or_path, mode)
    else:
        os.chmod(fd_or_path, mode)
