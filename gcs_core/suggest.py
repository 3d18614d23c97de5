""" "Did you mean": the closest known name to a typed one, in one wording everywhere a
name is typed (config keys, mission.toml keys and tables, effect ids, mission paths).

:func:`did_you_mean` gives the clause a message ends with; :func:`close_path` finds the
sibling a mistyped path most likely meant.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from pathlib import Path

#: similarity (difflib's ratio) a known name needs to be suggested: ``noize`` → ``noise``
#: is 0.8, ``onboard_atitude`` → ``onboard_attitude`` 0.97, unrelated words stay below
CUTOFF = 0.6


def closest(name: str, known: Iterable[str], cutoff: float = CUTOFF) -> str | None:
    """The known name closest to ``name`` (difflib's ratio ≥ ``cutoff``), or None."""
    close = difflib.get_close_matches(name, [str(k) for k in known], n=1, cutoff=cutoff)
    return close[0] if close else None


def did_you_mean(name: str, known: Iterable[str], cutoff: float = CUTOFF) -> str:
    """``; did you mean 'X'?`` for the closest known name, ``''`` when none is close."""
    close = closest(name, known, cutoff)
    return f"; did you mean '{close}'?" if close else ""


def close_path(path: str | Path, *, want_dir: bool = False, cutoff: float = CUTOFF) -> Path | None:
    """The existing sibling of a path that does not exist whose name is closest to its
    name (a directory when ``want_dir``), or None (also when the parent does not exist:
    only the last part is guessed)."""
    p = Path(path)
    parent = p.parent
    try:
        siblings = [c.name for c in parent.iterdir() if (c.is_dir() if want_dir else c.exists())]
    except OSError:
        return None
    close = closest(p.name, siblings, cutoff)
    return parent / close if close else None


def did_you_mean_path(path: str | Path, *, want_dir: bool = False) -> str:
    """``; did you mean 'DIR/NAME'?`` for the closest existing sibling, ``''`` when none."""
    close = close_path(path, want_dir=want_dir)
    return f"; did you mean '{close}'?" if close is not None else ""
