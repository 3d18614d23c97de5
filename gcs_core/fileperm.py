"""How GCS writes files: atomically, durably, with the usual permissions.

Every file GCS writes (configs, reports, CSV tables, plots, HDF5 stores, converted
mission directories) goes through one of three helpers here:

* :func:`atomic_path` — a temporary path in the destination's folder; on a clean exit
  the file is fsync-ed, given the usual mode, renamed over the destination with
  ``os.replace`` and the folder fsync-ed (so the rename itself survives a power cut);
  on an exception the temporary is removed and the destination is untouched;
* :func:`atomic_open` / :func:`write_atomic` — the same, for a file written through a
  handle or from one string/bytes value;
* :func:`atomic_directory` — a staging directory beside the destination; on a clean exit
  every file in it is fsync-ed and it replaces the destination in one step (Linux
  ``renameat2(RENAME_EXCHANGE)``; where that is missing, two renames).

A kill at any moment leaves the old file (directory) or the new one, never a mix; a
killed writer leaves at most a hidden temporary ``.<name>.*.tmp`` beside it.

``tempfile.mkstemp`` creates files readable by their owner only (0600). Reports,
configs, plots and data sets are not secrets: they get the mode an ordinary
``open(..., "w")`` would give, 0666 less the process umask (0644 with the usual umask
022), the same as the HDF5 files h5py creates.

The truth simulator (:mod:`gcs_core.sim.writer`) keeps its own few lines for this on
purpose: it imports nothing of the engine it is meant to check.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import shutil
import tempfile
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO

_lock = threading.Lock()


def _umask() -> int:
    with _lock:  # read without changing it for other threads for long
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def usual_mode() -> int:
    """0666 less the current umask: what ``open(..., "w")`` gives a new file."""
    return 0o666 & ~_umask()


def usual_dir_mode() -> int:
    """0777 less the current umask: what ``mkdir`` gives a new directory."""
    return 0o777 & ~_umask()


def make_usual(fd_or_path) -> None:
    """Give a file just written through ``mkstemp`` the usual permissions (module docstring)."""
    mode = usual_mode()
    if isinstance(fd_or_path, int):
        os.fchmod(fd_or_path, mode)
    else:
        os.chmod(fd_or_path, mode)


def fsync_path(path, *, directory: bool = False) -> None:
    """fsync a file or a directory by name (silently skipped where the system refuses)."""
    try:
        fd = os.open(path, os.O_RDONLY | (os.O_DIRECTORY if directory else 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _unlink(path) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` to write; it replaces ``path`` on a clean exit
    (module docstring). The folder must exist. A symbolic link is written through: the
    file it names is replaced and the link stays."""
    path = Path(path)
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        fsync_path(tmp)
        make_usual(tmp)
        os.replace(tmp, path)
    except BaseException:
        _unlink(tmp)
        raise
    fsync_path(path.parent, directory=True)


@contextlib.contextmanager
def atomic_open(
    path: str | os.PathLike, mode: str = "w", *, encoding: str | None = "utf-8", newline: str | None = None
) -> Iterator[IO]:
    """``open(path, mode)`` written atomically (:func:`atomic_path`); ``mode`` "w" or "wb"."""
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open writes a new file ('w' or 'wb'), not {mode!r}")
    with atomic_path(path) as tmp:
        if mode == "wb":
            with open(tmp, "wb") as fh:
                yield fh
        else:
            with open(tmp, "w", encoding=encoding, newline=newline) as fh:
                yield fh


def write_atomic(
    path: str | os.PathLike,
    data: str | bytes,
    *,
    encoding: str = "utf-8",
    newline: str | None = None,
    parents: bool = False,
) -> Path:
    """Write ``data`` to ``path`` atomically (:func:`atomic_path`); ``parents``: create the folder."""
    path = Path(path)
    if parents:
        path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, bytes):
        with atomic_open(path, "wb") as fh:
            fh.write(data)
    else:
        with atomic_open(path, "w", encoding=encoding, newline=newline) as fh:
            fh.write(data)
    return path


def write_atomic_set(files: Sequence[tuple[Path, str | bytes]]) -> list[Path]:
    """Write several files as a set: every one to a temporary beside it first (fsync-ed);
    only when all are written are they renamed into place. A failure (disk full) removes
    the temporaries and leaves no partial set behind."""
    staged: list[tuple[str, Path]] = []
    try:
        for path, data in files:
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
            staged.append((tmp, path))
            with os.fdopen(fd, "wb") as fh:
                fh.write(data.encode("utf-8") if isinstance(data, str) else data)
                fh.flush()
                os.fsync(fh.fileno())
            make_usual(tmp)
    except BaseException:
        for tmp, _ in staged:
            _unlink(tmp)
        raise
    for tmp, path in staged:
        os.replace(tmp, path)
    for folder in {path.parent for _, path in staged}:
        fsync_path(folder, directory=True)
    return [path for _, path in staged]


def probe_folder(folder: str | os.PathLike) -> None:
    """Create and remove a temporary file in ``folder``: raises the OSError a write there
    would meet (read-only, permissions, missing), so that it is met before the work."""
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".gcs-probe.", suffix=".tmp")
    os.close(fd)
    _unlink(tmp)


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step (Linux ``renameat2``); False where that is not available."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        return False
    ok = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0
    return ok


@contextlib.contextmanager
def atomic_directory(out: str | os.PathLike, *, mode: int | None = None) -> Iterator[Path]:
    """Yield an empty staging directory beside ``out``; on a clean exit it replaces ``out``
    (module docstring); on an exception it is removed and ``out`` is untouched.
    ``mode``: the new directory's permissions (``mkdtemp`` makes it private); default
    0777 less the umask, as ``mkdir`` gives."""
    out = Path(os.path.abspath(out))
    out.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    stage.chmod(usual_dir_mode() if mode is None else mode)
    try:
        yield stage
        for root, dirs, files in os.walk(stage):
            for name in files:
                fsync_path(os.path.join(root, name))
            for name in dirs:
                fsync_path(os.path.join(root, name), directory=True)
        fsync_path(stage, directory=True)
        if not out.exists():
            os.replace(stage, out)
        elif _exchange(stage, out):  # stage now holds the old directory
            shutil.rmtree(stage, ignore_errors=True)
        else:
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", suffix=".tmp", dir=out.parent))
            os.replace(out, old / "x")
            os.replace(stage, out)
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    fsync_path(out.parent, directory=True)
