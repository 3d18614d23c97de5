"""Where the TUI writes what the user did not name, and when it must ask first.

* :func:`safe_stem` turns a name read from a file (a mission's ``name``) into a file
  stem: a name is data, never a path, so ``victimdir/pyproject``, ``../x`` or ``/etc/x``
  cannot reach outside the chosen folder (issue 23 item 3).
* :func:`protected` says whether a file must never be a default save target: a file
  bundled with GCS (``sample_data/``) or tracked by git.
* :func:`comment_lines` counts the comments a config save would drop (the writer
  writes the config's values, not the file's text).
* :func:`free_name` is the first ``stem-N.suffix`` beside a file that does not exist.
"""

from __future__ import annotations

import re
import subprocess
import unicodedata
from pathlib import Path

import gcs_core

#: the bundled sample data: never a default save target
BUNDLED = Path(gcs_core.__file__).resolve().parent.parent / "sample_data"
#: the longest stem a default name gets (file systems allow 255 bytes)
MAX_STEM = 80
_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")


def safe_stem(name: str, fallback: str = "gcs") -> str:
    """A file stem made from ``name``: letters, digits, ``. _ + -`` (every other run of
    characters — ``/``, ``\\``, spaces, control characters — becomes one ``_``), no
    leading dots (no ``..`` or hidden files), at most :data:`MAX_STEM` characters;
    ``fallback`` when nothing is left."""
    text = unicodedata.normalize("NFKD", str(name)).encode("ascii", "ignore").decode("ascii")
    stem = _UNSAFE.sub("_", text).strip("._-")
    stem = re.sub(r"\.{2,}", ".", stem)[:MAX_STEM].rstrip("._-")
    return stem or fallback


def inside(folder: Path, name: str, suffix: str) -> Path:
    """``folder / (safe_stem(name) + suffix)`` — always a file directly in ``folder``."""
    return Path(folder) / f"{safe_stem(name)}{suffix}"


def protected(path: str | Path) -> bool:
    """True when ``path`` is bundled with GCS (under ``sample_data/``) or tracked by git."""
    p = Path(path).expanduser().resolve()
    if p == BUNDLED or BUNDLED in p.parents:
        return True
    if not p.is_file():
        return False
    try:
        done = subprocess.run(
            ["git", "-C", str(p.parent), "ls-files", "--error-unmatch", "--", p.name],
            capture_output=True,
            timeout=5,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return False
    return done.returncode == 0


def comment_lines(path: str | Path) -> int:
    """Lines of ``path`` holding a TOML comment (0 when it cannot be read)."""
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return 0
    return sum(1 for line in text.splitlines() if "#" in line)


def free_name(path: str | Path) -> Path:
    """``path`` if it does not exist, else the first ``<stem>-N<suffix>`` beside it that does not."""
    p = Path(path)
    n = 2
    while p.exists() or p.is_symlink():
        p = p.with_name(f"{Path(path).stem}-{n}{Path(path).suffix}")
        n += 1
    return p
