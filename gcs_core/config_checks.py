"""The analysis config's value checks (:mod:`gcs_core.config`): each refusal is one
:class:`~gcs_core.errors.ConfigError` naming the file and the full key."""

from __future__ import annotations

import difflib
import json
import math
import re
from typing import Any

from gcs_core.errors import ConfigError


def _fail(key: str | None, message: str, file) -> None:
    raise ConfigError(message, file=file, key=key or None)


def _require(cond: bool, key: str, message: str, file) -> None:
    if not cond:
        _fail(key, message, file)


def _quote(name: str) -> str:
    """A TOML key part, quoted when it is not a bare key (element names hold a dot)."""
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name, ensure_ascii=False)


def _show(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def _table(parent: dict, key: str, full: str, file) -> dict:
    v = parent.get(key, {})
    _require(isinstance(v, dict), full, f"must be a table, not {_show(v)}", file)
    return v


def _list(parent: dict, key: str, full: str, file) -> list:
    v = parent.get(key, [])
    _require(isinstance(v, list), full, f"must be a list, not {_show(v)}", file)
    return v


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _number(table: dict, key: str, default, file, *, positive=False, lo=None, hi=None, prefix="",
            integer=False, allow_inf=False):
    full = f"{prefix}{key}"
    if key not in table:
        return default
    v = table[key]
    _require(_is_number(v), full, f"must be a number, not {_show(v)}", file)
    v = float(v)
    _require(not math.isnan(v), full, "must be a number, not nan", file)
    if not (allow_inf and v == math.inf):
        _require(math.isfinite(v), full, f"must be finite, not {v}", file)
    if integer:
        _require(v == int(v), full, f"must be a whole number, not {v}", file)
    if positive:
        _require(v > 0, full, f"must be > 0, not {v}", file)
    if lo is not None:
        _require(v >= lo, full, f"must be ≥ {lo}, not {v}", file)
    if hi is not None:
        _require(v <= hi, full, f"must be ≤ {hi}, not {v}", file)
    return int(v) if integer else v


def _choice(table: dict, key: str, choices, default, full: str, file):
    v = table.get(key, default)
    _require(isinstance(v, str) and v in choices, full,
             f"must be one of {', '.join(choices)}, not {_show(v)}", file)
    return v


def _unknown(table: dict, known, prefix: str, file) -> None:
    extra = sorted(str(k) for k in set(table) - set(known))
    if extra:
        close = difflib.get_close_matches(extra[0], list(known), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        _fail(f"{prefix}{_quote(extra[0])}", f"unknown key{hint} (known: {', '.join(sorted(known))})", file)


def _pair(g: Any) -> bool:
    return (isinstance(g, list) and len(g) == 2 and all(_is_number(x) and math.isfinite(x) for x in g)
            and g[0] < g[1])
