"""What happens when the TUI meets a bug: one line and a log, never a traceback on the terminal.

Textual's own handler prints a full traceback after the screen is torn down and the app
exits with code 1, which the shell then saw as ``gcs tui``'s 0. :func:`record` writes
the traceback to a log file instead and returns the one line the CLI prints before it
exits 4 ("a bug in GCS", the README's exit codes).
"""

from __future__ import annotations

import os
import tempfile
import time
import traceback
from pathlib import Path

#: the exit code of an unhandled error (the CLI's EXIT_INTERNAL)
EXIT_INTERNAL = 4


def log_folder() -> Path:
    """``$XDG_STATE_HOME/gcs`` (default ``~/.local/state/gcs``), else the temp folder."""
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "gcs"


def write_log(error: BaseException) -> Path | None:
    """Write ``error``'s traceback to a new ``tui-crash-<time>.log``; its path (None if no
    folder could take it)."""
    text = "".join(traceback.format_exception(type(error), error, error.__traceback__))
    name = f"tui-crash-{time.strftime('%Y%m%dT%H%M%S')}-{os.getpid()}.log"
    for folder in (log_folder(), Path(tempfile.gettempdir())):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / name
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600)
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
            return path
        except OSError:
            continue
    return None


def record(error: BaseException) -> str:
    """The one line for an unhandled error in the TUI (its traceback written to a log)."""
    path = write_log(error)
    where = f"the traceback is in {path}" if path is not None else "no log could be written"
    message = " ".join(str(error).split())[:200]
    return f"internal error in the TUI: {type(error).__name__}: {message} — a bug in GCS; please report it ({where})"
