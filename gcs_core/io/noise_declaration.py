"""Writing a measured noise correlation into a mission's data book (mission.toml).

``gcs batch|discover --write-noise-correlation`` declares each sensor whose residuals show a
significant Gauss–Markov correlation (:mod:`gcs_core.noise.correlated`): the
sensor's ``[[sensor]]`` table gets ``noise_correlation_s = τ`` (docs/icd_extensions.md),
replacing a value already there, with a comment saying where it came from. The rest of the
file (comments, order, other keys) is kept as written; the file is replaced atomically.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

from gcs_core.errors import InputError
from gcs_core.fileperm import write_atomic

KEY = "noise_correlation_s"
_TABLE = re.compile(r"^\s*\[\[\s*sensor\s*\]\]\s*(#.*)?$")
_HEADER = re.compile(r"^\s*\[")
_NAME = re.compile(r"""^\s*name\s*=\s*["']([^"']*)["']""")
_KEYLINE = re.compile(rf"^\s*{KEY}\s*=")


def _tables(lines: list[str]) -> list[tuple[int, int, str | None]]:
    """``(first line, end line, sensor name)`` of every ``[[sensor]]`` table."""
    out = []
    starts = [i for i, ln in enumerate(lines) if _TABLE.match(ln)]
    for i in starts:
        end = next((j for j in range(i + 1, len(lines)) if _HEADER.match(lines[j])), len(lines))
        name = next((m.group(1) for ln in lines[i + 1 : end] if (m := _NAME.match(ln))), None)
        out.append((i, end, name))
    return out


def declare(mission_toml: str | Path, tau_s: Mapping[str, float], note: str = "") -> list[str]:
    """Write ``noise_correlation_s`` for each sensor in ``tau_s`` (name -> τ [s]) into
    ``mission_toml``; returns the sensors written. Raises InputError naming the file when
    a sensor has no table in it."""
    path = Path(mission_toml)
    lines = path.read_text(encoding="utf-8").splitlines()
    tables = {name: (i, end) for i, end, name in _tables(lines) if name is not None}
    missing = [n for n in tau_s if n not in tables]
    if missing:
        raise InputError(f"no [[sensor]] table named {', '.join(map(repr, missing))}", file=path)
    edits = []
    for name, tau in tau_s.items():
        i, end = tables[name]
        text = f"{KEY} = {float(tau):.6g}" + (f"  # {note}" if note else "")
        at = next((j for j in range(i + 1, end) if _KEYLINE.match(lines[j])), None)
        edits.append((at, i, end, text))
    # from the bottom up, so earlier positions stay valid
    for at, i, end, text in sorted(edits, key=lambda e: -(e[0] if e[0] is not None else e[2])):
        if at is not None:
            lines[at] = text
        else:
            j = end
            while j > i + 1 and not lines[j - 1].strip():  # before the blank lines closing the table
                j -= 1
            lines.insert(j, text)
    write_atomic(path, "\n".join(lines) + "\n")
    return list(tau_s)
