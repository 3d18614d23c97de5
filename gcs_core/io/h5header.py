"""The GCS header block of a GCS HDF5 file (SDF, SCDS, ASF): written, parsed, checked.

The first :data:`USERBLOCK` bytes (HDF5's user block) hold a text header: format, version,
file length and the SHA-256 of the rest of the file. It is checked before HDF5 reads
anything (:mod:`gcs_core.io.h5store`): HDF5 can loop forever on some damaged metadata, so a
damaged GCS file never reaches it.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from gcs_core.errors import DataFileError

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: the GCS header in the HDF5 user block (bytes HDF5 leaves to the application).
USERBLOCK = 512
GCS_MAGIC = b"GCS-HDF5"
HEADER_VERSION = 1


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
        fh.seek(USERBLOCK)
        block, _ = _header_block(fmt, version, fh.read())
        fh.seek(0)
        fh.write(block)


def _parse_header(head: bytes, size: int, path: Path, fmt: str, max_version: int) -> tuple[int, str]:
    """(length, sha256 hex) the GCS header block ``head`` claims, after checking it names
    ``fmt``, a readable version and the file's ``size`` (DataFileError otherwise)."""
    if size == 0:
        raise DataFileError("is empty (0 bytes), not an HDF5 file", file=path)
    if head.startswith(HDF5_SIGNATURE):
        raise DataFileError(f"is an HDF5 file but not a GCS {fmt} file (no GCS header block)", file=path)
    if not head.startswith(GCS_MAGIC):
        if head[USERBLOCK : USERBLOCK + len(HDF5_SIGNATURE)] == HDF5_SIGNATURE:
            raise DataFileError("has a damaged GCS header block", file=path)
        raise DataFileError("is not an HDF5 file (no HDF5 signature)", file=path)
    head = head[:USERBLOCK]
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
        raise DataFileError(f"has {size - length} bytes after its end ({length} bytes): the file is damaged", file=path)
    return length, digest


def _sha_refused(path: Path) -> DataFileError:
    return DataFileError("fails its checksum (SHA-256 of the whole file): the file is damaged", file=path)


def check_file(path: str | os.PathLike, fmt: str, *, max_version: int) -> None:
    """Check the GCS header block and the whole-file SHA-256 before HDF5 sees the file.

    HDF5 itself can loop forever on some damaged metadata, so a GCS file is only handed
    to it once its checksum holds. Raises DataFileError naming what is wrong.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(USERBLOCK + len(HDF5_SIGNATURE))
            _, digest = _parse_header(head, os.fstat(fh.fileno()).st_size, path, fmt, max_version)
            actual, _ = _file_digest(fh, USERBLOCK)
    except OSError as err:
        raise DataFileError(f"cannot be read ({err.strerror})", file=path) from None
    if actual != digest:
        raise _sha_refused(path)


def read_checked(path: str | os.PathLike, fmt: str, *, max_version: int) -> tuple[bytes, str]:
    """The whole file's bytes and their SHA-256 (hex, of the bytes after the header block),
    once :func:`check_file`'s checks hold on exactly these bytes (read once: what is checked
    is what is used). The caller holds the lock."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as err:
        raise DataFileError(f"cannot be read ({err.strerror})", file=path) from None
    _, digest = _parse_header(data[: USERBLOCK + len(HDF5_SIGNATURE)], len(data), path, fmt, max_version)
    actual = hashlib.sha256(memoryview(data)[USERBLOCK:]).hexdigest()
    if actual != digest:
        raise _sha_refused(path)
    return data, actual


def _header_block(fmt: str, version: int, body) -> tuple[bytes, str]:
    """(the GCS header block, sha256 hex) of a file whose bytes after the block are ``body``."""
    digest = hashlib.sha256(body).hexdigest()
    text = (
        f"{GCS_MAGIC.decode()} {HEADER_VERSION}\nformat {fmt}\nversion {version}\n"
        f"length {USERBLOCK + len(body)}\nsha256 {digest}\n"
    ).encode("ascii")
    return text.ljust(USERBLOCK, b"\0"), digest
