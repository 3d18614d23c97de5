"""The one place GCS opens its HDF5 files (SDF, SCDS, ASF).

Guarantees every GCS data set gets:

* **Atomic writes.** A file is written to a temporary file in the same directory,
  closed, given its header, ``fsync``-ed, renamed over the destination with ``os.replace``
  and the directory ``fsync``-ed (:func:`gcs_core.fileperm.atomic_path`): a crash or a kill
  at any moment leaves either the old file or the new one, never a mixture. Appending
  (SCDS versions, ASF solutions) copies the existing groups into the new file, so earlier
  groups are carried over byte for byte.
* **Locking between GCS processes** (:mod:`gcs_core.io.locks`): ``fcntl.flock`` on a
  sidecar ``<file>.lock`` opened without following links, never truncated; writers
  exclusive, readers shared, the wait as long as an append can take. HDF5's own file
  locking is turned off (``locking=False``): ours is the only one.
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

import glob
import hashlib
import logging
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from typing import overload

import h5py
import numpy as np

from gcs_core.errors import DataFileError
from gcs_core.fileperm import atomic_path
from gcs_core.io.locks import locked, resolved
from gcs_core.io.outputs import refuse_not_a_file, refuse_replacing

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
            text, nul, padding = head.partition(b"\0")
            first = text.split(b"\n", 1)[0]
            if padding.strip(b"\0") or not nul or not (first[len(GCS_MAGIC) : len(GCS_MAGIC) + 1] == b" "):
                raise DataFileError("has a damaged GCS header block", file=path)
            for line in text.decode("ascii", "replace").splitlines()[1:]:
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
def atomic_create(path: str | os.PathLike, fmt: str, version: int, *, appending: bool = False) -> Iterator[h5py.File]:
    """Write a new GCS HDF5 file atomically, under the exclusive lock.

    Yields an ``h5py.File`` built in memory (written to a temporary file in the
    destination directory on a clean exit, by Python: a full disk is one clean error),
    with ``gcs_format``, ``gcs_format_version``, ``created_utc`` and ``gcs_version``
    already set. On a clean exit the file is closed, synced and renamed over ``path``;
    on an exception it is removed and ``path`` is untouched. A file of another kind GCS
    recognises (:func:`gcs_core.io.outputs.file_kind`) is never replaced, nor an SCDS or
    ASF unless ``appending`` (:func:`append_group`).
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
                f = h5py.File(
                    tmp,
                    "w",
                    driver="core",
                    backing_store=False,
                    libver=LIBVER,
                    locking=False,
                    userblock_size=USERBLOCK,
                )
                try:
                    f.attrs[FORMAT_ATTR] = fmt
                    f.attrs[VERSION_ATTR] = np.int64(version)
                    f.attrs[CREATED_ATTR] = utc_now()
                    f.attrs[GCS_VERSION_ATTR] = gcs_version()
                    yield f
                    f.flush()
                    image = f.id.get_file_image()
                finally:
                    f.close()
                with open(tmp, "wb") as fh:
                    if image.startswith(HDF5_SIGNATURE):  # the image leaves the user block out
                        fh.write(bytes(USERBLOCK))
                    fh.write(image)
                del image
                _write_header(tmp, fmt, version)  # hashed and written; atomic_path syncs it
        except OSError as err:  # disk full, read-only directory, ...
            raise DataFileError(f"cannot be written ({_one_line(err)})", file=path) from None


def check_appendable(path: str | os.PathLike, fmt: str, collection: str, *, max_version: int) -> None:
    """Refuse to append to ``path`` unless every check holds: the whole-file SHA-256, then
    every object's own checksum, no links, numbered groups as GCS writes them. Run by
    :func:`append_group`, and by the ``gcs`` command before a fit whose result it appends."""
    try:
        verify(path, fmt, max_version=max_version)
        with open_read(path, fmt, max_version=max_version) as src:
            numbered_names(src, collection)
    except DataFileError as err:
        raise DataFileError(
            f"{err.message}; refusing to append to it (the earlier versions would be at risk)", file=path
        ) from None


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
    path = resolved(path)  # a symbolic link is written through
    with locked(path, exclusive=True):
        existing: list[int] = []
        if path.exists():
            check_appendable(path, fmt, collection, max_version=max_version)
        with atomic_create(path, fmt, version, appending=True) as dst:
            if path.exists():
                with open_read(path, fmt, max_version=max_version) as src:
                    for key, value in src.attrs.items():
                        if key not in (VERSION_ATTR, GCS_VERSION_ATTR):
                            dst.attrs[key] = value
                    for name in src:
                        src.copy(src[name], dst, name=name)
                    existing = [int(n) for n in numbered_names(src, collection)]
            number = max(existing, default=0) + 1
            group = dst.require_group(collection).create_group(f"{number:05d}")
            build(group, number)
        return number


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
