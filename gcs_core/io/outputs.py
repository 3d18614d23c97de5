"""Output paths checked before any work starts.

A typo in ``--sdf``, ``--report`` or ``--out`` must not cost a calibration history, a
mission directory or 28 s of fitting. :func:`check_output_file` and
:func:`check_output_dir` run before the work and refuse, in one line naming the path:

* a path that is a directory, a FIFO, a device or a socket where a file is written, or a
  file where a folder is written; a loop of symbolic links;
* a file of another kind GCS recognises (:func:`file_kind`: a GCS SCDS, ASF or SDF
  file, any other HDF5 file, a mission directory): a report never replaces an SCDS, an
  SDF never replaces an SCDS or a vendor's HDF5; a calibration history (SCDS) or an
  attitude history (ASF) is only ever appended to, never replaced;
* a read-only file, or a folder GCS cannot create files in (tried with a temporary file);
* the same file named by two outputs of one command.

A symbolic link as an output is written through (:func:`gcs_core.fileperm.atomic_path`
replaces the file the link names, and the link stays); the check follows it too.
"""

from __future__ import annotations

import errno
import os
import stat
from collections.abc import Mapping
from pathlib import Path

from gcs_core.errors import DataFileError, InputError
from gcs_core.fileperm import probe_folder

GCS_MAGIC = b"GCS-HDF5"
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
USERBLOCK = 512
#: what each kind is called in the messages.
KIND_NAMES = {
    "SCDS": "a calibration history (GCS SCDS file)",
    "ASF": "an attitude history (GCS ASF file)",
    "SDF": "a GCS Standard Data File (SDF)",
    "GCS": "a GCS HDF5 file",
    "HDF5": "an HDF5 file not written by GCS",
    "mission": "a mission directory (it holds mission.toml)",
    "directory": "a directory",
    "fifo": "a FIFO (named pipe), not a file",
    "device": "a device, not a file",
    "socket": "a socket, not a file",
}
#: kinds only ever appended to.
APPEND_ONLY = ("SCDS", "ASF")


def special_kind(mode: int) -> str | None:
    """'fifo', 'device', 'socket' for such a ``st_mode``; None for a file or directory."""
    if stat.S_ISFIFO(mode):
        return "fifo"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "device"
    if stat.S_ISSOCK(mode):
        return "socket"
    return None


def _stat(path: Path) -> os.stat_result | None:
    try:
        return os.stat(path)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise InputError("is a loop of symbolic links", file=path) from None
        if err.errno in (errno.ENOENT, errno.ENOTDIR):
            return None
        raise InputError(f"cannot be looked up ({err.strerror})", file=path) from None


def file_kind(path: str | os.PathLike) -> str | None:
    """What GCS recognises at ``path``, links followed (None: nothing, or an ordinary file).

    'SCDS', 'ASF', 'SDF', 'TRADE', … (the format named in the GCS header block, 'GCS' when
    it names none);
    'HDF5' for any other HDF5 file (a signature at byte 0 or after the user block);
    'mission' for a directory holding ``mission.toml``, 'directory' for another;
    'fifo', 'device', 'socket'. Never blocks on a FIFO (it is not opened).
    """
    path = Path(path)
    st = _stat(path)
    if st is None:
        return None
    if stat.S_ISDIR(st.st_mode):
        return "mission" if (path / "mission.toml").is_file() else "directory"
    special = special_kind(st.st_mode)
    if special is not None:
        return special
    try:
        with open(path, "rb") as fh:
            head = fh.read(USERBLOCK + len(HDF5_SIGNATURE))
    except OSError:
        return None
    if head.startswith(GCS_MAGIC):
        for line in head[:USERBLOCK].split(b"\n")[1:4]:
            if line.startswith(b"format "):
                fmt = line[7:].strip(b"\0 ").decode("ascii", "replace")
                return fmt if fmt.isascii() and fmt.isalnum() else "GCS"
        return "GCS"
    if head.startswith(HDF5_SIGNATURE) or head[USERBLOCK:].startswith(HDF5_SIGNATURE):
        return "HDF5"
    return None


def kind_name(found: str) -> str:
    """``found`` (:func:`file_kind`) in words, for messages."""
    return KIND_NAMES.get(found, f"a GCS {found} file")


def refuse_other_kind(path: str | os.PathLike, fmt: str, what: str) -> None:
    """Refuse to replace ``path`` with a GCS ``fmt`` file when it holds something else GCS
    recognises (an SCDS, a mission directory, a vendor's HDF5, …)."""
    found = file_kind(path)
    if found is not None and found != fmt:
        raise InputError(f"is {kind_name(found)}; writing {what} would replace it: choose another path", file=path)


def _probe_folder(folder: Path, *, shown: Path) -> None:
    """Create and remove a temporary file in ``folder`` (InputError if that fails)."""
    try:
        probe_folder(folder)
    except OSError as err:
        raise InputError(f"cannot write in folder {folder} ({err.strerror or err})", file=shown) from None


def _make_folder(folder: Path, shown: Path) -> None:
    if _stat(folder) is not None and not folder.is_dir():
        raise InputError(f"folder {folder} is not a directory", file=shown)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"cannot create the folder {folder} ({err.strerror or err})", file=shown) from None


def check_output_file(path: str | os.PathLike, *, kind: str, what: str, append: bool = False) -> Path:
    """Check an output file before the work (module docstring); returns ``path``.

    ``kind``: what will be written ('SDF', 'SCDS', 'ASF', or 'text' for JSON, TOML, CSV);
    ``what``: its name in messages ("the SDF"); ``append``: the file is appended to
    (SCDS, ASF). The folder is created when missing.
    """
    path = Path(path)
    st = _stat(path)
    found = file_kind(path) if st is not None else None
    if found in ("mission", "directory", "fifo", "device", "socket"):
        raise InputError(f"is {KIND_NAMES[found]}: cannot write {what} there", file=path)
    if found is not None and found != kind:
        raise InputError(f"is {kind_name(found)}; writing {what} would replace it: choose another path", file=path)
    if found in APPEND_ONLY and not append:
        raise InputError(f"is {kind_name(found)}, which GCS only appends to: choose another path", file=path)
    if st is not None and found is None and kind not in ("text",) and st.st_size > 0:
        raise InputError(f"is a file but not a GCS {kind} file; writing {what} would replace it", file=path)
    real = Path(os.path.realpath(path))
    if st is not None and (not st.st_mode & 0o222 or not os.access(real, os.W_OK)):  # root too: no w bits
        raise InputError(f"is read-only: cannot write {what}", file=path)
    _make_folder(real.parent, path)
    _probe_folder(real.parent, shown=path)
    return path


def check_output_dir(path: str | os.PathLike, *, what: str) -> Path:
    """Check an output folder before the work: a directory or nothing, writable; returns it.

    A missing folder is not created here; its nearest existing parent must be writable.
    """
    path = Path(path)
    found = file_kind(path)
    if found is not None and found not in ("directory", "mission"):
        raise InputError(f"is {kind_name(found)}, not a folder: cannot write {what} there", file=path)
    if _stat(path) is not None and not path.is_dir():
        raise InputError(f"is a file, not a folder: cannot write {what} there", file=path)
    probe = Path(os.path.realpath(path))
    while _stat(probe) is None and probe != probe.parent:
        probe = probe.parent
    if not probe.is_dir():
        raise InputError(f"{probe} is not a directory: cannot write {what}", file=path)
    _probe_folder(probe, shown=path)
    return path


def check_distinct(outputs: Mapping[str, str | os.PathLike | None]) -> None:
    """Refuse one file named by two outputs (``{"--report": path, "--scds": path}``)."""
    seen: dict[str, str] = {}
    for option, p in outputs.items():
        if not p:
            continue
        key = os.path.realpath(p)
        if key in seen:
            raise InputError(f"named by both {seen[key]} and {option}: give each output its own file", file=p)
        seen[key] = option


def refuse_not_a_file(path: Path, fmt: str) -> None:
    """Refuse, before opening, a GCS ``fmt`` file that is missing, a directory, a FIFO, a
    device, a socket or a loop of links (``DataFileError``)."""
    try:
        st = os.stat(path)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise DataFileError("is a loop of symbolic links", file=path) from None
        if err.errno in (errno.ENOENT, errno.ENOTDIR):
            raise DataFileError(f"{fmt} file not found", file=path) from None
        raise DataFileError(f"cannot be read ({err.strerror})", file=path) from None
    if stat.S_ISDIR(st.st_mode):
        raise DataFileError(f"{fmt} file is a directory", file=path)
    special = special_kind(st.st_mode)
    if special is not None:
        raise DataFileError(f"is {KIND_NAMES[special]}", file=path)


def refuse_replacing(path: Path, fmt: str, appending: bool) -> None:
    """Refuse to replace a file of another kind GCS recognises with a GCS ``fmt`` file, or
    an SCDS/ASF unless ``appending`` (``DataFileError``)."""
    found = file_kind(path)
    if found is None or (found == fmt and (appending or fmt not in APPEND_ONLY)):
        return
    if found == fmt:
        raise DataFileError(f"is {kind_name(found)}, which GCS only appends to: not replaced", file=path)
    raise DataFileError(f"is {kind_name(found)}; a GCS {fmt} file would replace it: not written", file=path)
