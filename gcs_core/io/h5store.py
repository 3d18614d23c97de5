"""The one place GCS opens its HDF5 files (SDF, SCDS, ASF).

Guarantees every GCS data set gets:

* **Atomic writes.** A file is written to a temporary file in the same directory,
  closed, given its header, ``fsync``-ed, renamed over the destination with ``os.replace``
  and the directory ``fsync``-ed (:func:`gcs_core.fileperm.atomic_path`): a crash or a kill
  at any moment leaves either the old file or the new one, never a mixture. Appending
  (SCDS versions, ASF solutions) copies the existing groups into the new file, so earlier
  groups are carried over byte for byte.
* **Locking between GCS processes.** ``fcntl.flock`` on a sidecar ``<file>.lock``:
  writers hold it exclusively, readers shared. A process that cannot get it within
  :data:`LOCK_WAIT_S` gets :class:`~gcs_core.errors.DataFileError` "... is in use by
  another GCS process (pid N)". HDF5's own file locking is turned off
  (``locking=False``): ours is the only one. Locks are re-entrant within a process.
  Sidecar lock files are left in place (removing them would race with waiters).
* **Checksums.** The first 512 bytes (HDF5's user block) hold a text header: format,
  version, file length and the SHA-256 of the rest of the file. It is checked before
  HDF5 reads anything. HDF5 can loop forever on some damaged metadata, so a damaged
  GCS file never reaches it. Inside, every dataset is chunked with the ``fletcher32``
  filter and the metadata carries HDF5's own checksums (``libver`` 1.10 layout).
* **A format name and version** on every file (root attributes ``gcs_format`` and
  ``gcs_format_version``), checked when the file is opened.

Every problem with a file (missing, not HDF5, truncated, corrupt, checksum failure,
wrong format, locked) becomes one ``DataFileError(message, file=path)``.
"""

from __future__ import annotations

import errno
import fcntl
import glob
import hashlib
import logging
import os
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import overload

import h5py
import numpy as np

from gcs_core.errors import DataFileError
from gcs_core.fileperm import atomic_path

log = logging.getLogger(__name__)

FORMAT_ATTR = "gcs_format"
VERSION_ATTR = "gcs_format_version"
CREATED_ATTR = "created_utc"
GCS_VERSION_ATTR = "gcs_version"
#: HDF5 1.10 file layout: superblock v3 and object headers v2, with metadata checksums.
LIBVER = ("v110", "v110")
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: the GCS header in the HDF5 user block (bytes HDF5 leaves to the application).
USERBLOCK = 512
GCS_MAGIC = b"GCS-HDF5"
HEADER_VERSION = 1
#: seconds a process waits for a lock held by another GCS process before giving up.
LOCK_WAIT_S = 1.0
_POLL_S = 0.02

#: the errors h5py raises for unreadable files and objects (KeyError for a corrupt
#: object header, OSError for a failed filter or a truncated file).
H5_ERRORS = (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError)


def gcs_version() -> str:
    """Version string of the installed GCS package ("unknown" when not installed)."""
    try:
        from importlib.metadata import PackageNotFoundError, version

        return version("gcs")
    except PackageNotFoundError:  # not installed (source checkout)
        return "0+unknown"


def utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


# --- locking --------------------------------------------------------------------------


class _Held:
    __slots__ = ("fd", "exclusive", "count")

    def __init__(self, fd: int, exclusive: bool):
        self.fd, self.exclusive, self.count = fd, exclusive, 0


_held: dict[str, _Held] = {}
_held_guard = threading.Lock()


def lock_path(path: str | os.PathLike) -> Path:
    """The sidecar lock file of ``path``."""
    path = Path(path)
    return path.with_name(path.name + ".lock")


def _holder_pid(fd: int) -> str:
    try:
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
        return str(int(text.split()[0]))
    except (OSError, ValueError, IndexError):
        return "unknown"


def _flock(fd: int, exclusive: bool, path: Path, wait: float) -> None:
    op = (fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH) | fcntl.LOCK_NB
    deadline = time.monotonic() + wait
    while True:
        try:
            fcntl.flock(fd, op)
            return
        except OSError as err:
            if err.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise DataFileError(f"cannot lock ({err.strerror})", file=path) from None
        if time.monotonic() >= deadline:
            raise DataFileError(f"is in use by another GCS process (pid {_holder_pid(fd)})", file=path)
        time.sleep(_POLL_S)


@contextmanager
def locked(path: str | os.PathLike, *, exclusive: bool, wait: float | None = None) -> Iterator[None]:
    """Hold the GCS lock of ``path`` (exclusive for writers, shared for readers).

    Re-entrant within one process: an inner request reuses the outer lock, upgrading
    shared to exclusive when asked. A shared lock in a directory where the lock file
    cannot be created (read-only media) is skipped: nothing can write there anyway.
    """
    path = Path(path)
    wait = LOCK_WAIT_S if wait is None else wait
    lpath = lock_path(path)
    key = os.path.abspath(lpath)
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
    try:
        fd = os.open(lpath, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    except OSError as err:
        if not exclusive and err.errno in (errno.EROFS, errno.EACCES, errno.EPERM):
            log.debug("%s: no lock file (%s); reading unlocked", path, err.strerror)
            yield
            return
        raise DataFileError(f"cannot create the lock file {lpath.name} ({err.strerror})", file=path) from None
    try:
        _flock(fd, exclusive, path, wait)
        if exclusive or os.fstat(fd).st_size == 0:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
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


# --- opening --------------------------------------------------------------------------


def _one_line(err: BaseException) -> str:
    lines = str(err).strip().splitlines()
    text = lines[0] if lines else type(err).__name__
    return text.strip("'\"")


def _describe_open_failure(path: Path, err: BaseException) -> DataFileError:
    try:
        size = path.stat().st_size
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError as e:
        return DataFileError(f"cannot be read ({e.strerror})", file=path)
    if size == 0:
        return DataFileError("is empty (0 bytes), not an HDF5 file", file=path)
    if head != HDF5_SIGNATURE and not head.startswith(GCS_MAGIC):
        return DataFileError("is not an HDF5 file (no HDF5 signature)", file=path)
    text = _one_line(err)
    if "truncated" in text:
        return DataFileError(f"is truncated ({size} bytes; {text})", file=path)
    return DataFileError(f"is corrupt or unreadable (HDF5: {text})", file=path)


def corrupt(path: str | os.PathLike, err: BaseException, where: str = "") -> DataFileError:
    """A DataFileError for an error met while reading an open file."""
    text = _one_line(err)
    place = f" at {where}" if where else ""
    if "filter" in text or "checksum" in text:
        return DataFileError(f"fails its checksum{place}: the file is corrupt ({text})", file=path)
    return DataFileError(f"is corrupt or not laid out as expected{place} ({text})", file=path)


def _file_digest(fh, start: int) -> tuple[str, int]:
    """(sha256 hex of the bytes from ``start`` to the end, file length)."""
    fh.seek(start)
    h = hashlib.sha256()
    length = start
    while chunk := fh.read(1 << 20):
        h.update(chunk)
        length += len(chunk)
    return h.hexdigest(), length


def _write_header(path: Path, fmt: str, version: int) -> None:
    """Fill the user block of a closed file with the GCS header (see module docstring)."""
    with open(path, "r+b") as fh:
        digest, length = _file_digest(fh, USERBLOCK)
        text = (
            f"{GCS_MAGIC.decode()} {HEADER_VERSION}\nformat {fmt}\nversion {version}\n"
            f"length {length}\nsha256 {digest}\n"
        ).encode("ascii")
        fh.seek(0)
        fh.write(text.ljust(USERBLOCK, b"\0"))


def check_file(path: str | os.PathLike, fmt: str, *, max_version: int) -> None:
    """Check the GCS header block and the whole-file SHA-256 before HDF5 sees the file.

    HDF5 itself can loop forever on some damaged metadata, so a GCS file is only handed
    to it once its checksum holds. Raises DataFileError naming what is wrong.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(USERBLOCK)
            size = os.fstat(fh.fileno()).st_size
            if size == 0:
                raise DataFileError("is empty (0 bytes), not an HDF5 file", file=path)
            if head.startswith(HDF5_SIGNATURE):
                raise DataFileError(f"is an HDF5 file but not a GCS {fmt} file (no GCS header block)", file=path)
            if not head.startswith(GCS_MAGIC):
                fh.seek(USERBLOCK)
                if fh.read(len(HDF5_SIGNATURE)) == HDF5_SIGNATURE:
                    raise DataFileError("has a damaged GCS header block", file=path)
                raise DataFileError("is not an HDF5 file (no HDF5 signature)", file=path)
            fields = {}
            for line in head.rstrip(b"\0").decode("ascii", "replace").splitlines()[1:]:
                key, _, value = line.partition(" ")
                fields[key] = value.strip()
            try:
                found, version = fields["format"], int(fields["version"])
                length, digest = int(fields["length"]), fields["sha256"]
            except (KeyError, ValueError):
                raise DataFileError("has a damaged GCS header block", file=path) from None
            if found != fmt:
                raise DataFileError(f"is a GCS {found} file, not {fmt}", file=path)
            if version > max_version:
                raise DataFileError(
                    f"was written by a newer GCS ({fmt} format version {version}; this GCS reads up to {max_version})",
                    file=path,
                )
            if size < length:
                raise DataFileError(f"is truncated ({size} of {length} bytes)", file=path)
            if size > length:
                raise DataFileError(
                    f"has {size - length} bytes after its end ({length} bytes): the file is damaged", file=path
                )
            actual, _ = _file_digest(fh, USERBLOCK)
    except OSError as err:
        raise DataFileError(f"cannot be read ({err.strerror})", file=path) from None
    if actual != digest:
        raise DataFileError("fails its checksum (SHA-256 of the whole file): the file is damaged", file=path)


@contextmanager
def open_read(
    path: str | os.PathLike, fmt: str, *, max_version: int, lock: bool = True, check: bool = True
) -> Iterator[h5py.File]:
    """Open a GCS HDF5 file for reading, checked, under a shared lock.

    Parameters
    ----------
    path : the file.
    fmt : expected ``gcs_format`` ("SDF", "SCDS", "ASF").
    max_version : newest format version this GCS reads.
    lock : take the shared lock (False only when the caller holds one).
    check : verify the GCS header and whole-file checksum first (:func:`check_file`);
        False hands even a damaged file to HDF5, to salvage what it can (HDF5 may hang
        on damaged metadata).

    Errors raised by h5py inside the ``with`` body (checksum failures, corrupt object
    headers, missing groups) are turned into :class:`DataFileError` as well.
    """
    path = Path(path)
    if not path.exists():
        raise DataFileError(f"{fmt} file not found", file=path)
    if path.is_dir():
        raise DataFileError(f"{fmt} file is a directory", file=path)
    ctx = locked(path, exclusive=False) if lock else _nothing()
    with ctx:
        if check:
            check_file(path, fmt, max_version=max_version)
        try:
            f = h5py.File(path, "r", locking=False)
        except H5_ERRORS as err:
            raise _describe_open_failure(path, err) from None
        try:
            try:
                found = f.attrs.get(FORMAT_ATTR)
                version = f.attrs.get(VERSION_ATTR)
            except H5_ERRORS as err:
                raise corrupt(path, err, "the root attributes") from None
            if isinstance(found, bytes):
                found = found.decode("utf-8", "replace")
            if found is None:
                raise DataFileError(
                    f"is an HDF5 file but not a GCS {fmt} file (no '{FORMAT_ATTR}' attribute)", file=path
                )
            if found != fmt:
                raise DataFileError(f"is a GCS {found} file, not {fmt}", file=path)
            try:
                version = int(version)
            except (TypeError, ValueError):
                raise DataFileError(f"has no valid '{VERSION_ATTR}' attribute", file=path) from None
            if version > max_version:
                raise DataFileError(
                    f"was written by a newer GCS ({fmt} format version {version}; this GCS reads up to {max_version})",
                    file=path,
                )
            try:
                yield f
            except DataFileError:
                raise
            except H5_ERRORS as err:
                raise corrupt(path, err) from None
        finally:
            try:
                f.close()
            except H5_ERRORS:
                pass


@contextmanager
def _nothing() -> Iterator[None]:
    yield


def verify(path: str | os.PathLike, fmt: str, *, max_version: int) -> int:
    """Read every dataset and attribute of the file (every checksum checked).

    Returns the number of datasets read; raises DataFileError on the first failure.
    """
    path = Path(path)
    count = 0
    with open_read(path, fmt, max_version=max_version) as f:
        names: list[str] = []
        try:
            f.visit(names.append)
        except H5_ERRORS as err:
            raise corrupt(path, err, "the group index") from None
        for name in names:
            try:
                obj = f[name]
                dict(obj.attrs)
                if isinstance(obj, h5py.Dataset):
                    obj[()]
                    count += 1
            except H5_ERRORS as err:
                raise corrupt(path, err, f"/{name}") from None
    return count


# --- writing --------------------------------------------------------------------------


def _remove_stale_temps(path: Path) -> None:
    """Temporary files left by a killed writer (we hold the exclusive lock)."""
    for stale in glob.glob(os.path.join(glob.escape(str(path.parent)), f".{glob.escape(path.name)}.*.tmp")):
        try:
            os.unlink(stale)
        except OSError:
            pass


@contextmanager
def atomic_create(path: str | os.PathLike, fmt: str, version: int) -> Iterator[h5py.File]:
    """Write a new GCS HDF5 file atomically, under the exclusive lock.

    Yields an ``h5py.File`` open on a temporary file in the destination directory,
    with ``gcs_format``, ``gcs_format_version``, ``created_utc`` and ``gcs_version``
    already set. On a clean exit the file is closed, synced and renamed over ``path``;
    on an exception it is removed and ``path`` is untouched.
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise DataFileError("directory does not exist", file=path.parent)
    with locked(path, exclusive=True):
        _remove_stale_temps(path)
        try:
            with atomic_path(path) as tmp:
                with h5py.File(tmp, "w", libver=LIBVER, locking=False, userblock_size=USERBLOCK) as f:
                    f.attrs[FORMAT_ATTR] = fmt
                    f.attrs[VERSION_ATTR] = np.int64(version)
                    f.attrs[CREATED_ATTR] = utc_now()
                    f.attrs[GCS_VERSION_ATTR] = gcs_version()
                    yield f
                _write_header(tmp, fmt, version)  # hashed and written; atomic_path syncs it
        except OSError as err:  # disk full, read-only directory, ...
            raise DataFileError(f"cannot be written ({_one_line(err)})", file=path) from None


def append_group(
    path: str | os.PathLike,
    fmt: str,
    version: int,
    collection: str,
    build: Callable[[h5py.Group, int], None],
    *,
    max_version: int,
) -> int:
    """Append one numbered group ``/<collection>/NNNNN`` to an append-only file.

    The existing file (if any) is first checked (:func:`check_file`: header and
    whole-file SHA-256); a file that fails is refused, never rewritten. Its groups and
    root attributes are copied into a new temporary file, ``build(group, number)``
    fills the new group, and the result replaces the old file atomically. Returns the
    new number (1, 2, ...).
    """
    path = Path(path)
    with locked(path, exclusive=True):
        existing: list[int] = []
        if path.exists():
            try:  # the whole-file SHA-256 covers every byte, every earlier group
                check_file(path, fmt, max_version=max_version)
            except DataFileError as err:
                raise DataFileError(
                    f"{err.message}; refusing to append to it (the earlier versions would be at risk)", file=path
                ) from None
        with atomic_create(path, fmt, version) as dst:
            if path.exists():
                with open_read(path, fmt, max_version=max_version) as src:
                    for key, value in src.attrs.items():
                        if key not in (VERSION_ATTR, GCS_VERSION_ATTR):
                            dst.attrs[key] = value
                    for name in src:
                        src.copy(src[name], dst, name=name)
                    if collection in src:
                        existing = [int(n) for n in src[collection] if n.isdigit()]
            number = max(existing, default=0) + 1
            group = dst.require_group(collection).create_group(f"{number:05d}")
            build(group, number)
        return number


def numbered_names(f: h5py.File, collection: str) -> list[str]:
    """The numbered groups ``/<collection>/NNNNN`` of an append-only file, oldest first."""
    return sorted(n for n in f[collection] if n.isdigit()) if collection in f else []


def pick_numbered(f: h5py.File, collection: str, n: int | None, what: str, path: Path) -> h5py.Group:
    """Group ``n`` of ``collection`` (the latest when ``n`` is None).

    ``what`` names one group for the messages ("attitude solution", "calibration
    version"): an empty file, or a number outside the file's range, is refused with
    the range it holds.
    """
    available = numbered_names(f, collection)
    if not available:
        raise DataFileError(f"holds no {what}s", file=path)
    name = available[-1] if n is None else f"{int(n):05d}"
    if name not in available:
        raise DataFileError(f"has no {what} {n} ({what}s {int(available[0])} to {int(available[-1])})", file=path)
    return f[collection][name]


def write_array(group: h5py.Group, name: str, data, *, attrs: dict | None = None) -> h5py.Dataset:
    """A chunked, fletcher32-checksummed dataset (strings stored as UTF-8 bytes)."""
    a = np.asarray(data)
    if a.dtype.kind in "UO":
        a = np.array([str(s).encode("utf-8") for s in a.reshape(-1)], dtype=bytes).reshape(a.shape)
        if a.dtype.itemsize == 0:
            a = a.astype("S1")
    if a.ndim == 0:
        a = a.reshape(1)
    kwargs: dict = {"fletcher32": True}
    if a.size == 0:
        kwargs.update(chunks=(1,) * a.ndim, maxshape=(None,) * a.ndim)
    else:
        kwargs.update(chunks=True)
    ds = group.create_dataset(name, data=a, **kwargs)
    for k, v in (attrs or {}).items():
        ds.attrs[k] = v
    return ds


def read_strings(ds: h5py.Dataset) -> list[str]:
    """A dataset written by :func:`write_array` from strings, back as str."""
    return [v.decode("utf-8") if isinstance(v, bytes) else str(v) for v in ds[()].reshape(-1)]


@overload
def attr_str(obj, key: str, default: str) -> str: ...
@overload
def attr_str(obj, key: str, default: None = None) -> str | None: ...
def attr_str(obj, key: str, default: str | None = None) -> str | None:
    value = obj.attrs.get(key, default)
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return None if value is None else str(value)
