"""How the TOML readers parse, judge and quote values (the analysis config, :mod:`gcs_core.config`,
and mission.toml, :mod:`gcs_core.io.mission`): one wording for both.

Each reader raises its own error with the file, line and key; these functions give the
words: a value shown as its ``repr`` cut to 40 characters, a key part quoted as TOML
needs it, and the complaint about a value that should be a finite number.
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import os

    from gcs_core.errors import GcsError

#: characters of a value shown in a message
SHOWN = 40


class LocatedError(Protocol):
    """An error class that takes the message and ``file``, ``line``, ``column``
    (like :class:`~gcs_core.errors.InputError` and :class:`~gcs_core.errors.ConfigError`)."""

    def __call__(
        self,
        message: str,
        *,
        file: str | os.PathLike | None = ...,
        line: int | None = ...,
        column: int | str | None = ...,
    ) -> GcsError: ...


def show(value: Any) -> str:
    """``repr(value)``, cut to :data:`SHOWN` characters (with ``...``)."""
    try:
        text = repr(value)
    except ValueError:  # an integer past Python's 4300-digit limit
        text = f"<an integer of {digits(value)} digits>"
    return text if len(text) <= SHOWN else text[: SHOWN - 3] + "..."


def quote(name: str) -> str:
    """A TOML key part, quoted when it is not a bare key (element names hold a dot)."""
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name, ensure_ascii=False)


def is_number(value: Any) -> bool:
    """An int or float, not a bool (TOML's ``true`` is not 1)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def digits(value: int) -> int:
    """Decimal digits of an integer, without converting it to text (at most one too many)."""
    return int(abs(value).bit_length() * 0.30103) + 1


def number_complaint(value: Any, *, allow_inf: bool = False) -> str | None:
    """Why ``value`` is not a finite number (``+inf`` allowed with ``allow_inf``), or None."""
    if not is_number(value):
        return f"must be a number, not {show(value)}"
    try:
        v = float(value)
    except OverflowError:  # an integer beyond 1.8e308
        return f"must be a number below 1e308, not an integer of {digits(value)} digits"
    if math.isnan(v):
        return "must be a number, not nan"
    if not (allow_inf and v == math.inf) and not math.isfinite(v):
        return f"must be finite, not {v}"
    return None


def decode(raw: bytes, path, error: LocatedError) -> str:
    """UTF-8 text of a TOML file, or ``error`` ("not UTF-8 text") at the bad byte's line and column.
    A UTF-8 byte-order mark (as some Windows editors write) is accepted and dropped."""
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as err:
        line = raw[: err.start].count(b"\n") + 1
        raise error(
            f"not UTF-8 text (byte 0x{raw[err.start]:02x})",
            file=path,
            line=line,
            column=err.start - (raw.rfind(b"\n", 0, err.start) + 1) + 1,
        ) from None


def loads(text: str, path, error: LocatedError) -> dict:
    """``tomllib.loads`` with its errors as ``error`` at a line and column (``error`` takes
    the message and ``file``, ``line``, ``column``, like :class:`~gcs_core.errors.InputError`)."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        msg = str(err).splitlines()[0] if str(err) else "invalid TOML"
        m = re.search(r"\s*\(at line (\d+), column (\d+)\)\s*$", msg)
        if m:
            raise error(
                f"TOML syntax error: {msg[: m.start()]}", file=path, line=int(m.group(1)), column=int(m.group(2))
            ) from None
        m = re.search(r"\s*\(at end of document\)\s*$", msg)
        if m:
            raise error(
                f"TOML syntax error at the end of the file: {msg[: m.start()]}",
                file=path,
                line=max(1, text.count("\n") + (not text.endswith("\n"))),
            ) from None
        raise error(f"TOML syntax error: {msg}", file=path) from None
    except RecursionError:
        raise error("TOML nesting too deep", file=path) from None
    except ValueError:  # int() past Python's 4300-digit limit, raised through tomllib
        m = re.search(r"[0-9_]{4000,}", text)
        line = text.count("\n", 0, m.start()) + 1 if m else None
        column = m.start() - text.rfind("\n", 0, m.start()) if m else None
        raise error("a number of more than 4300 digits", file=path, line=line, column=column) from None
