"""The analysis config's value checks (:mod:`gcs_core.config`): each refusal is one
:class:`~gcs_core.errors.ConfigError` naming the file and the full key."""

from __future__ import annotations

import difflib
import math
from typing import Any

from gcs_core.errors import ConfigError
from gcs_core.toml_values import is_number, number_complaint, quote, show


def _fail(key: str | None, message: str, file) -> None:
    raise ConfigError(message, file=file, key=key or None)


def _require(cond: bool, key: str, message: str, file) -> None:
    if not cond:
        _fail(key, message, file)


def _table(parent: dict, key: str, full: str, file) -> dict:
    v = parent.get(key, {})
    _require(isinstance(v, dict), full, f"must be a table, not {show(v)}", file)
    return v


def _list(parent: dict, key: str, full: str, file) -> list:
    v = parent.get(key, [])
    _require(isinstance(v, list), full, f"must be a list, not {show(v)}", file)
    return v


def _number(
    table: dict, key: str, default, file, *, positive=False, lo=None, hi=None, prefix="", integer=False, allow_inf=False
):
    full = f"{prefix}{key}"
    if key not in table:
        return default
    v = table[key]
    complaint = number_complaint(v, allow_inf=allow_inf)
    if complaint:
        _fail(full, complaint, file)
    v = float(v)
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
    _require(isinstance(v, str) and v in choices, full, f"must be one of {', '.join(choices)}, not {show(v)}", file)
    return v


def _unknown(table: dict, known, prefix: str, file) -> None:
    extra = sorted(str(k) for k in set(table) - set(known))
    if extra:
        close = difflib.get_close_matches(extra[0], list(known), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        _fail(f"{prefix}{quote(extra[0])}", f"unknown key{hint} (known: {', '.join(sorted(known))})", file)


def _pair(g: Any) -> bool:
    return isinstance(g, list) and len(g) == 2 and all(is_number(x) and math.isfinite(x) for x in g) and g[0] < g[1]
