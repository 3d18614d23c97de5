"""The one place GCS opens its HDF5 files (SDF, SCDS, ASF).

Guarantees every GCS data set gets:

* **Atomic writes.** A file is written to a temporary file in the same directory,
  closed, given its header, ``fsync``-ed, renamed over the destination with ``os.replace``
  and the directory ``fsync``-ed (:func:`gcs_core.fileperm.atomic_path`): a crash or a kill
  at any moment leaves either the old file or the new one, never a mixture. Appending
  (SCDS versions, ASF solutions; :mod:`gcs_core.io.h5append`) adds the new group to the
  checked bytes of the existing file in memory, so earlier groups are carried over as
  the bytes they were.
* **Locking between GCS processes** (:mod:`gcs_core.io.locks`): ``fcntl.flock`` on a
  sidecar ``<file>.lock`` opened without following links, never truncated; writers
  exclusive, readers shared, the wait as long as an append can take. HDF5's own file
  locking is turned off (``locking=False``): ours is the only one.
* **Checksums.** The first 512 bytes (HDF5's user block) hold a text header: format,
  version, file length and the SHA-256 of the rest of the file
  (:mod:`gcs_core.io.h5header`). It is checked before
  HDF5 reads anything. HDF5 can loop forever on some damaged metadata, so a damaged
  GCS file never reaches it. Inside, every dataset is chunked with the ``fletcher32``
  filter and the metadata carries HDF5's own checksums (``libver`` 1.10 layout).
* **A format name and version** on every file (root attributes ``gcs_format`` and
  ``gcs_format_version``), checked when the file is opened.

Every problem with a file (missing, not HDF5, truncated, corrupt, checksum failure,
wrong format, locked) becomes one ``DataFileError(message, file=path)``.
"""

from __future__ import annotations

import functools
import glob
import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import overload

import h5py
import numpy as np

from gcs_core.errors import DataFileError
from gcs_core.fileperm import atomic_path
from gcs_core.io.h5header import (  # noqa: F401 — check_file, _write_header: part of this module's API
    GCS_MAGIC,
    HDF5_SIGNATURE,
    USERBLOCK,
    _header_block,
    _write_header,
    check_file,
    read_checked,
)
from gcs_core.io.locks import locked, resolved
from gcs_core.io.outputs import refuse_not_a_file, refuse_replacing

log = logging.getLogger(__name__)

FORMAT_ATTR = "gcs_format"
VERSION_ATTR = "gcs_format_version"
CREATED_ATTR = "created_utc"
GCS_VERSION_ATTR = "gcs_version"
#: HDF5 1.10 file layout: superblock v3 and object headers v2, with metadata checksums.
LIBVER = ("v110", "v110")

#: the errors h5py raises for unreadable files and objects (KeyError for a corrupt
#: object header, OSError for a failed filter or a truncated file).
H5_ERRORS = (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError)


@functools.cache
def gcs_version() -> str:
    """Version string of the installed GCS package ("unknown" when not installed); read
    once per process (the package metadata lookup costs milliseconds, every append asked)."""
    try:
        from importlib.metadata import PackageNotFoundError, version

        return version("gcs")
    except PackageNotFoundError:  # not installed (source checkout)
        return "0+unknown"


def utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


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


def open_image(data: bytes, path: Path, *, writable: bool = False) -> h5py.File:
    """An ``h5py.File`` on a file's bytes in memory (HDF5's core driver, nothing written
    back); ``path`` names the file in messages. Writable: new objects in the 1.10 layout."""
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_fapl_core(1 << 20, False)
    fapl.set_file_image(data)
    fapl.set_libver_bounds(h5py.h5f.LIBVER_V110, h5py.h5f.LIBVER_V110)
    try:
        fid = h5py.h5f.open(os.fsencode(path.name), h5py.h5f.ACC_RDWR if writable else h5py.h5f.ACC_RDONLY, fapl=fapl)
    except H5_ERRORS as err:
        raise _describe_open_failure(path, err) from None
    return h5py.File(fid)


def check_root(f: h5py.File, path: Path, fmt: str, max_version: int) -> None:
    """The root attributes name ``fmt`` and a version this GCS reads (DataFileError)."""
    try:
        found = f.attrs.get(FORMAT_ATTR)
        version = f.attrs.get(VERSION_ATTR)
    except H5_ERRORS as err:
        raise corrupt(path, err, "the root attributes") from None
    if isinstance(found, bytes):
        found = found.decode("utf-8", "replace")
    if found is None:
        raise DataFileError(f"is an HDF5 file but not a GCS {fmt} file (no '{FORMAT_ATTR}' attribute)", file=path)
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
    refuse_not_a_file(path, fmt)  # missing, a directory, a FIFO, a loop of links: refused unopened
    ctx = locked(path, exclusive=False) if lock else _nothing()
    with ctx:
        if check:
            check_file(path, fmt, max_version=max_version)
        try:
            f = h5py.File(path, "r", locking=False)
        except H5_ERRORS as err:
            raise _describe_open_failure(path, err) from None
        try:
            if check:
                refuse_links(f, path)
            check_root(f, path, fmt, max_version)
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


def refuse_links(f: h5py.File, path: Path) -> None:
    """Refuse soft and external links: GCS writes none, and an external link reads
    another file (``/etc/passwd``) as if it were part of this one."""
    found: list[str] = []

    def visit(name: bytes, info) -> int | None:  # the low-level walk: no object opened per link
        if info.type != h5py.h5l.TYPE_HARD:
            kind = "an external" if info.type == h5py.h5l.TYPE_EXTERNAL else "a soft"
            found.append(f"/{name.decode('utf-8', 'replace')} is {kind} link")
            return 1  # stop
        return None

    try:
        f.id.links.visit(visit, info=True)
    except H5_ERRORS as err:
        raise corrupt(path, err, "the group index") from None
    if found:
        raise DataFileError(f"holds links GCS never writes ({found[0]}): refused", file=path)


def verify(path: str | os.PathLike, fmt: str, *, max_version: int) -> int:
    """Read every dataset and attribute of the file (every checksum checked).

    Returns the number of datasets read; raises DataFileError on the first failure.
    """
    path = Path(path)
    with open_read(path, fmt, max_version=max_version) as f:
        return verify_objects(f, path)


def verify_objects(f: h5py.File, path: Path) -> int:
    """Read every dataset and attribute of the open file ``f`` (:func:`verify`)."""
    count = 0
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
def atomic_create(
    path: str | os.PathLike,
    fmt: str,
    version: int,
    *,
    appending: bool = False,
    image: bytes | None = None,
    written: dict | None = None,
) -> Iterator[h5py.File]:
    """Write a new GCS HDF5 file atomically, under the exclusive lock.

    Yields an ``h5py.File`` built in memory (written to a temporary file in the
    destination directory on a clean exit, by Python: a full disk is one clean error),
    with ``gcs_format``, ``gcs_format_version``, ``created_utc`` and ``gcs_version``
    already set. On a clean exit the file is closed, synced and renamed over ``path``;
    on an exception it is removed and ``path`` is untouched. A file of another kind GCS
    recognises (:func:`gcs_core.io.outputs.file_kind`) is never replaced, nor an SCDS or
    ASF unless ``appending`` (:func:`gcs_core.io.h5append.append_group`).

    ``image``: start from these bytes of a checked GCS file (:func:`read_checked`) instead
    of an empty file, their objects kept as they are (``gcs_format_version`` and
    ``gcs_version`` set to this writer's). ``written``, when given, receives the new
    file's ``sha256`` (of the bytes after the header block).
    """
    path = resolved(path)  # a symbolic link is written through
    if not path.parent.is_dir():
        raise DataFileError("directory does not exist", file=path.parent)
    with locked(path, exclusive=True):
        refuse_replacing(path, fmt, appending)
        _remove_stale_temps(path)
        try:
            with atomic_path(path) as tmp:
                # built in memory (HDF5's core driver), written out by Python: a full disk
                # is one OSError here, never an HDF5 write failure (destructor noise, a crash)
                if image is None:
                    f = h5py.File(
                        tmp,
                        "w",
                        driver="core",
                        backing_store=False,
                        libver=LIBVER,
                        locking=False,
                        userblock_size=USERBLOCK,
                    )
                else:
                    f = open_image(image, path, writable=True)
                try:
                    if image is None:
                        f.attrs[FORMAT_ATTR] = fmt
                        f.attrs[CREATED_ATTR] = utc_now()
                    f.attrs[VERSION_ATTR] = np.int64(version)
                    f.attrs[GCS_VERSION_ATTR] = gcs_version()
                    yield f
                    f.flush()
                    new = f.id.get_file_image()
                finally:
                    f.close()
                # HDF5's image leaves the user block out (it starts at the superblock)
                body = memoryview(new) if new.startswith(HDF5_SIGNATURE) else memoryview(new)[USERBLOCK:]
                block, digest = _header_block(fmt, version, body)
                with open(tmp, "wb") as fh:
                    fh.write(block)
                    fh.write(body)
                del body, new
                if written is not None:
                    written["sha256"] = digest
        except OSError as err:  # disk full, read-only directory, ...
            raise DataFileError(f"cannot be written ({_one_line(err)})", file=path) from None


#: at most this many digits in a version (solution) number.
MAX_NUMBER_DIGITS = 9


def numbered_names(f: h5py.File, collection: str) -> list[str]:
    """The numbered groups ``/<collection>/NNNNN`` of an append-only file, oldest first
    (sorted as numbers: 100000 after 99999).

    A collection that is not a group, a numbered entry that is not a group, or a number
    of more than :data:`MAX_NUMBER_DIGITS` digits is refused (``DataFileError``).
    """
    if collection not in f:
        return []
    path = Path(f.filename)
    group = f[collection]
    if not isinstance(group, h5py.Group):
        raise DataFileError(f"is corrupt: /{collection} is a dataset, not a group", file=path)
    names = [n for n in group if n.isascii() and n.isdigit()]
    for n in names:
        if len(n.lstrip("0")) > MAX_NUMBER_DIGITS:
            raise DataFileError(
                f"is corrupt: /{collection}/{n} has a number of {len(n)} digits (at most {MAX_NUMBER_DIGITS})",
                file=path,
            )
        if not isinstance(group[n], h5py.Group):
            raise DataFileError(f"is corrupt: /{collection}/{n} is a dataset, not a group", file=path)
    return sorted(names, key=int)


def pick_numbered(f: h5py.File, collection: str, n: int | None, what: str, path: Path) -> h5py.Group:
    """Group ``n`` of ``collection`` (the latest when ``n`` is None).

    ``what`` names one group for the messages ("attitude solution", "calibration
    version"): an empty file, or a number outside the file's range, is refused with
    the range it holds.
    """
    available = numbered_names(f, collection)
    if not available:
        raise DataFileError(f"holds no {what}s", file=path)
    by_number = {int(x): x for x in available}
    name = available[-1] if n is None else by_number.get(int(n))
    if name is None:
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
