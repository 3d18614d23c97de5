"""Locks between GCS processes on their HDF5 files (SDF, SCDS, ASF).

``fcntl.flock`` on a sidecar ``<file>.lock``: writers hold it exclusively, readers
shared. Locks are re-entrant within a process. Sidecar lock files are left in place
(removing them would race with waiters).

The sidecar sits in a folder others may write to, so it is handled as untrusted:

* it is opened with ``O_NOFOLLOW | O_CREAT`` and never truncated: a symbolic link
  planted at ``cal.h5.lock`` is refused with a reason instead of being followed, and a
  regular file that is not a GCS lock file (more than one hard link, or longer than a
  lock record) is refused rather than overwritten;
* the lock belongs to the file a path resolves to (symbolic links followed), so two
  links to one SCDS share one lock;
* the PID record is written in place, padded to a fixed width (:data:`RECORD_BYTES`).

How long a process waits: an append copies the whole file, so a writer holding the lock
can keep it for as long as that takes (about 1 s for 200 MB on a slow disk, more on a
network one). :func:`wait_s` allows :data:`LOCK_WAIT_S` plus :data:`LOCK_WAIT_S_PER_MB`
per megabyte of the file; after :data:`SAY_AFTER_S` the wait is announced in one log
warning naming the holder's PID. Only past that does ``DataFileError`` "… is in use by
another GCS process (pid N)" end it.
"""

from __future__ import annotations

import errno
import fcntl
import logging
import os
import stat
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from gcs_core.errors import DataFileError

log = logging.getLogger(__name__)

#: seconds a process waits for a lock held by another GCS process, at least.
LOCK_WAIT_S = 60.0
#: seconds added per megabyte of the locked file (an append copies every byte, and a
#: slow or network disk copies 2 MB/s and up: 0.5 s/MB covers it).
LOCK_WAIT_S_PER_MB = 0.5
#: a wait longer than this is announced (one log warning).
SAY_AFTER_S = 1.0
#: bytes of the PID record at the start of a lock file.
RECORD_BYTES = 16
_POLL_S = 0.02


class _Held:
    __slots__ = ("fd", "exclusive", "count")

    def __init__(self, fd: int, exclusive: bool):
        self.fd, self.exclusive, self.count = fd, exclusive, 0


_held: dict[str, _Held] = {}
_held_guard = threading.Lock()


def resolved(path: str | os.PathLike) -> Path:
    """The file ``path`` names, symbolic links followed (a dangling link: its target).

    A loop of links is refused (``DataFileError`` "is a loop of symbolic links").
    """
    path = Path(path)
    try:
        os.stat(path)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise DataFileError("is a loop of symbolic links", file=path) from None
    return Path(os.path.realpath(path))


def lock_path(path: str | os.PathLike) -> Path:
    """The sidecar lock file of ``path`` (of the file it resolves to)."""
    path = resolved(path)
    return path.with_name(path.name + ".lock")


def wait_s(path: str | os.PathLike) -> float:
    """How long to wait for the lock of ``path`` (module docstring)."""
    try:
        size_mb = os.stat(path).st_size / 1e6
    except OSError:
        size_mb = 0.0
    return LOCK_WAIT_S + LOCK_WAIT_S_PER_MB * size_mb


def _holder_pid(fd: int) -> str:
    try:
        text = os.pread(fd, RECORD_BYTES, 0).decode("ascii", "replace").strip()
        return str(int(text.split()[0]))
    except (OSError, ValueError, IndexError):
        return "unknown"


def _flock(fd: int, exclusive: bool, path: Path, wait: float) -> None:
    op = (fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH) | fcntl.LOCK_NB
    start = time.monotonic()
    said = False
    while True:
        try:
            fcntl.flock(fd, op)
            if said:
                log.warning("%s: lock obtained after %.1f s", path, time.monotonic() - start)
            return
        except OSError as err:
            if err.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise DataFileError(f"cannot lock ({err.strerror})", file=path) from None
        waited = time.monotonic() - start
        if waited >= wait:
            raise DataFileError(f"is in use by another GCS process (pid {_holder_pid(fd)})", file=path)
        if not said and waited >= SAY_AFTER_S:
            said = True
            log.warning(
                "%s: in use by another GCS process (pid %s); waiting for it, up to %.0f s",
                path,
                _holder_pid(fd),
                wait,
            )
        time.sleep(_POLL_S)


def _open_lock_file(lpath: Path, path: Path, exclusive: bool) -> int | None:
    """The lock file's descriptor (None: a reader on read-only media, unlocked)."""
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC | os.O_NONBLOCK
    try:
        fd = os.open(lpath, flags, 0o666)  # the umask applies
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise DataFileError(
                f"lock file {lpath.name} is a symbolic link: refusing to follow it (remove it)", file=path
            ) from None
        if not exclusive and err.errno in (errno.EROFS, errno.EACCES, errno.EPERM):
            log.debug("%s: no lock file (%s); reading unlocked", path, err.strerror)
            return None
        raise DataFileError(f"cannot create the lock file {lpath.name} ({err.strerror})", file=path) from None
    st = os.fstat(fd)
    why = ""
    if not stat.S_ISREG(st.st_mode):
        why = "is not a regular file"
    elif st.st_nlink > 1:
        why = f"has {st.st_nlink} hard links (another file's name)"
    elif st.st_size > RECORD_BYTES:
        why = f"holds {st.st_size} bytes, more than a GCS lock record ({RECORD_BYTES})"
    if why:
        os.close(fd)
        raise DataFileError(f"lock file {lpath.name} {why}: refusing to use it (remove it)", file=path)
    return fd


@contextmanager
def locked(path: str | os.PathLike, *, exclusive: bool, wait: float | None = None) -> Iterator[None]:
    """Hold the GCS lock of ``path`` (exclusive for writers, shared for readers).

    Re-entrant within one process: an inner request reuses the outer lock, upgrading
    shared to exclusive when asked. A shared lock in a directory where the lock file
    cannot be created (read-only media) is skipped: nothing can write there anyway.
    ``wait``: seconds to wait for another process (default :func:`wait_s`).
    """
    path = resolved(path)
    wait = wait_s(path) if wait is None else wait
    lpath = path.with_name(path.name + ".lock")
    key = str(lpath)
    with _held_guard:
        held = _held.get(key)
    if held is not None:
        upgraded = exclusive and not held.exclusive
        if upgraded:
            _flock(held.fd, True, path, wait)
            held.exclusive = True
        held.count += 1
        try:
            yield
        finally:
            held.count -= 1
            if upgraded:
                fcntl.flock(held.fd, fcntl.LOCK_SH)
                held.exclusive = False
        return
    fd = _open_lock_file(lpath, path, exclusive)
    if fd is None:
        yield
        return
    try:
        _flock(fd, exclusive, path, wait)
        if exclusive or os.fstat(fd).st_size == 0:  # the record, in place, never truncated
            os.pwrite(fd, f"{os.getpid()}\n".rjust(RECORD_BYTES).encode(), 0)
        held = _Held(fd, exclusive)
        held.count = 1
        with _held_guard:
            _held[key] = held
        try:
            yield
        finally:
            with _held_guard:
                _held.pop(key, None)
    finally:
        os.close(fd)  # releases the flock
