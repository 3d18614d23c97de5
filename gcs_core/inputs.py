"""What a path given as input is, said plainly before anything opens it.

``Path.is_file()`` answers False for a FIFO, a device, a loop of symbolic links and a
file behind a folder GCS may not enter, so each would be reported as "not found"; worse,
reading a FIFO blocks forever and reading ``/dev/zero`` never ends. :func:`path_kind`
looks once (``os.stat``, which opens nothing) and :func:`refuse_unreadable` turns every
kind but a regular file (or a directory, where one is wanted) into one line.
"""

from __future__ import annotations

import errno
import os
import stat

from gcs_core.errors import InputError

#: what each kind that is neither a file nor a directory is called in messages.
NOT_A_FILE = {
    "fifo": "is a FIFO (named pipe), not a file",
    "device": "is a device, not a file",
    "socket": "is a socket, not a file",
    "loop": "is a loop of symbolic links",
}


def path_kind(path: str | os.PathLike) -> tuple[str, str]:
    """``(kind, detail)``: kind 'file', 'dir', 'missing', 'loop', 'fifo', 'device',
    'socket' or 'error' (``detail``: the system's words, e.g. "Permission denied")."""
    try:
        st = os.stat(path)
    except OSError as err:
        if err.errno == errno.ELOOP:
            return "loop", ""
        if err.errno in (errno.ENOENT, errno.ENOTDIR):
            return "missing", ""
        return "error", err.strerror or str(err)
    except ValueError as err:  # a NUL in the name
        return "error", str(err)
    mode = st.st_mode
    if stat.S_ISREG(mode):
        return "file", ""
    if stat.S_ISDIR(mode):
        return "dir", ""
    if stat.S_ISFIFO(mode):
        return "fifo", ""
    if stat.S_ISSOCK(mode):
        return "socket", ""
    return "device", ""


def refuse_unreadable(path: str | os.PathLike, what: str, *, error=InputError, **where) -> str:
    """The kind of ``path`` ('file', 'dir' or 'missing'); every other kind is refused with
    ``error`` (a FIFO, a device, a loop of links, a path the system will not look up)."""
    kind, detail = path_kind(path)
    if kind in NOT_A_FILE:
        raise error(f"{what} {NOT_A_FILE[kind]}", file=path, **where)
    if kind == "error":
        raise error(f"{what} cannot be read ({detail})", file=path, **where)
    return kind


def check_directory_readable(path: str | os.PathLike, what: str) -> None:
    """Refuse a directory GCS may not list or enter (``chmod 000``)."""
    try:
        os.listdir(path)
    except OSError as err:
        raise InputError(f"{what} cannot be read ({err.strerror or err})", file=path) from None
