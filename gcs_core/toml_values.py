"""How the TOML readers judge and quote values (the analysis config, :mod:`gcs_core.config`,
and mission.toml, :mod:`gcs_core.sidp.mission`): one wording for both.

Each reader raises its own error with the file, line and key; these functions give the
words: a value shown as its ``repr`` cut to 40 characters, a key part quoted as TOML
needs it, and the complaint about a value that should be a finite number.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

#: characters of a value shown in a message
SHOWN = 40


def show(value: Any) -> str:
    """``repr(value)``, cut to :data:`SHOWN` characters (with ``...``)."""
    text = repr(value)
    return text if len(text) <= SHOWN else text[:SHOWN - 3] + "..."


def quote(name: str) -> str:
    """A TOML key part, quoted when it is not a bare key (element names hold a dot)."""
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name, ensure_ascii=False)


def is_number(value: Any) -> bool:
    """An int or float, not a bool (TOML's ``true`` is not 1)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def number_complaint(value: Any, *, allow_inf: bool = False) -> str | None:
    """Why ``value`` is not a finite number (``+inf`` allowed with ``allow_inf``), or None."""
    if not is_number(value):
        return f"must be a number, not {show(value)}"
    v = float(value)
    if math.isnan(v):
        return "must be a number, not nan"
    if not (allow_inf and v == math.inf) and not math.isfinite(v):
        return f"must be finite, not {v}"
    return None
