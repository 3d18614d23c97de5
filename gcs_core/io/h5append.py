"""Appending one numbered group to an append-only GCS HDF5 file (SCDS versions, ASF solutions).

An append runs under the file's exclusive lock (:mod:`gcs_core.io.locks`) and reads the
existing file **once**, into memory (:func:`gcs_core.io.h5store.read_checked`):

1. the GCS header block and the SHA-256 of exactly the bytes read;
2. every object of those bytes (:func:`check_objects`): no soft or external link, every
   attribute and every dataset read (every fletcher32 chunk checksum), the numbered groups as
   GCS writes them. A file that fails is refused and never rewritten;
3. the new group is added to that in-memory image (HDF5's core driver opened read-write on
   the bytes): the earlier groups stay the bytes they were, nothing is copied object by
   object; the new file is written out by Python with a new header, ``fsync``-ed and renamed
   over the old one (:func:`gcs_core.io.h5store.atomic_create`).

Step 2 is skipped when **the same bytes** were already checked or written by this process:
their SHA-256 equals one this process recorded for the file after checking it or after
writing it (:data:`_CHECKED`). The SHA-256 is of the bytes just read, never the one the
header claims, so a file changed by anyone in any way (another process, another writer, a
hand edit, a forged header) no longer matches and is checked object by object again.

Cost per append (`benchmarks/fleet_throughput.py` prints it): the SHA-256 and one copy of
the file at memory speed, plus HDF5 opening the image; the object walk once per file and
process. The object-by-object copy and the three checksum passes of the earlier
implementation grew by about 2 ms per stored entry and file.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path

import h5py

from gcs_core.errors import DataFileError
from gcs_core.io import h5store
from gcs_core.io.locks import locked, resolved

__all__ = ["append_group", "check_appendable", "check_objects"]

#: (resolved path, format, collection) -> SHA-256 of the bytes this process last checked
#: or wrote there (module docstring)
_CHECKED: dict[tuple[str, str, str], str] = {}
_CHECKED_GUARD = threading.Lock()


def check_objects(data: bytes, path: Path, fmt: str, collection: str, *, max_version: int) -> None:
    """Every object of the file image ``data`` as GCS writes them (module docstring, step 2)."""
    f = h5store.open_image(data, path)
    try:
        h5store.check_root(f, path, fmt, max_version)
        h5store.refuse_links(f, path)
        h5store.verify_objects(f, path)
        h5store.numbered_names(f, collection)
    except DataFileError:
        raise
    except h5store.H5_ERRORS as err:
        raise h5store.corrupt(path, err) from None
    finally:
        try:
            f.close()
        except h5store.H5_ERRORS:
            pass


def _checked_image(path: Path, fmt: str, collection: str, *, max_version: int) -> bytes:
    """The file's bytes once every check holds (the caller holds a lock on it)."""
    key = (str(path), fmt, collection)
    try:
        data, digest = h5store.read_checked(path, fmt, max_version=max_version)
        with _CHECKED_GUARD:
            known = _CHECKED.get(key) == digest
        if not known:
            check_objects(data, path, fmt, collection, max_version=max_version)
            with _CHECKED_GUARD:
                _CHECKED[key] = digest
    except DataFileError as err:
        raise DataFileError(
            f"{err.message}; refusing to append to it (the earlier versions would be at risk)", file=path
        ) from None
    return data


def check_appendable(path: str | os.PathLike, fmt: str, collection: str, *, max_version: int) -> None:
    """Refuse to append to ``path`` unless every check holds: the whole-file SHA-256, then
    every object's own checksum, no links, numbered groups as GCS writes them. Run by
    :func:`append_group`, and by the ``gcs`` command before a fit whose result it appends."""
    path = resolved(path)
    with locked(path, exclusive=False):
        _checked_image(path, fmt, collection, max_version=max_version)


def append_group(
    path: str | os.PathLike,
    fmt: str,
    version: int,
    collection: str,
    build: Callable[[h5py.Group, int], None],
    *,
    max_version: int,
) -> int:
    """Append one numbered group ``/<collection>/NNNNN`` to an append-only file (module
    docstring); ``build(group, number)`` fills it. Returns the new number (1, 2, ...)."""
    path = resolved(path)  # a symbolic link is written through
    with locked(path, exclusive=True):
        image = _checked_image(path, fmt, collection, max_version=max_version) if path.exists() else None
        written: dict = {}
        with h5store.atomic_create(path, fmt, version, appending=True, image=image, written=written) as dst:
            existing = [int(n) for n in h5store.numbered_names(dst, collection)] if image is not None else []
            number = max(existing, default=0) + 1
            group = dst.require_group(collection).create_group(f"{number:05d}")
            build(group, number)
        del image
        with _CHECKED_GUARD:
            _CHECKED[(str(path), fmt, collection)] = written["sha256"]
        return number
