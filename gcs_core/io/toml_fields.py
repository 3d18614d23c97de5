"""Values of a TOML file checked with the line and key of each refusal (ICD §3).

``tomllib`` keeps no positions: :class:`Locator` finds a table's or key's line by a light
scan of the text, and :class:`Ctx` turns a complaint into an
:class:`~gcs_core.errors.InputError` naming the file, that line and the dotted key. The
value readers below are shared by mission.toml's readers (:mod:`gcs_core.io.mission`,
:mod:`gcs_core.io.orbit_spec`).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gcs_core.errors import InputError
from gcs_core.inputs import NOT_A_FILE, path_kind
from gcs_core.toml_values import number_complaint, show

__all__ = ["Locator", "Ctx", "number", "show", "numbers", "string", "existing_file", "optional_file"]

# --- locating keys in the text --------------------------------------------------------

_HEADER = re.compile(r"\s*(\[\[|\[)\s*([A-Za-z0-9_\-\.\"' ]+?)\s*\]\]?\s*(?:#.*)?$")
_KEYLINE = re.compile(r"\s*([A-Za-z0-9_\-]+|\"[^\"]*\"|'[^']*')\s*=")


class Locator:
    """Best-effort line numbers of tables and keys (tomllib keeps none)."""

    def __init__(self, text: str):
        self.tables: dict[tuple[str, int], int] = {}
        self.keys: dict[tuple[str, int, str], int] = {}
        current, index = "", 0
        counts: dict[str, int] = {}
        for lineno, line in enumerate(text.splitlines(), start=1):
            h = _HEADER.match(line)
            if h:
                current = h.group(2).replace(" ", "").replace('"', "").replace("'", "")
                index = counts.get(current, 0) + 1 if h.group(1) == "[[" else 1
                counts[current] = index
                self.tables.setdefault((current, index), lineno)
                continue
            k = _KEYLINE.match(line)
            if k:
                self.keys.setdefault((current, index, k.group(1).strip("\"'")), lineno)

    def line(self, table: str, key: str | None = None, index: int = 1) -> int | None:
        if key is not None and (table, index, key) in self.keys:
            return self.keys[(table, index, key)]
        return self.tables.get((table, index))


@dataclass
class Ctx:
    file: Path
    where: Locator

    def error(self, message: str, key: str, table: str = "", index: int = 1, tkey: str | None = None) -> InputError:
        return InputError(message, file=self.file, line=self.where.line(table, tkey, index), key=key)


# --- values ---------------------------------------------------------------------------


def number(ctx: Ctx, value: Any, key: str, table: str, index: int, tkey: str) -> float:
    complaint = number_complaint(value)
    if complaint:
        raise ctx.error(complaint, key, table, index, tkey)
    return float(value)


def numbers(ctx: Ctx, value: Any, size: int, key: str, table: str, index: int, tkey: str) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != size:
        raise ctx.error(f"must be a list of {size} numbers, not {show(value)}", key, table, index, tkey)
    return tuple(number(ctx, v, f"{key}[{i}]", table, index, tkey) for i, v in enumerate(value))


def string(ctx: Ctx, value: Any, key: str, table: str, index: int = 1, tkey: str | None = None) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ctx.error(f"must be a non-empty string, not {show(value)}", key, table, index, tkey)
    return value.strip()


def existing_file(
    ctx: Ctx, root: Path, value: Any, key: str, table: str, what: str, index: int = 1, tkey: str = "file"
) -> Path:
    rel = string(ctx, value, key, table, index, tkey)
    if "\x00" in rel:
        raise ctx.error("file name holds a NUL character", key, table, index, tkey)
    path = Path(rel) if os.path.isabs(rel) else root / rel
    try:
        is_file, is_dir = path.is_file(), path.is_dir()
    except (OSError, ValueError) as err:
        raise ctx.error(f"{what} file {rel!r} cannot be looked up ({err})", key, table, index, tkey) from None
    if is_dir:
        raise ctx.error(f"{what} file {rel!r} is a directory, not a file", key, table, index, tkey)
    if not is_file:
        kind, detail = path_kind(path)
        if kind in NOT_A_FILE:
            raise ctx.error(f"{what} file {rel!r} {NOT_A_FILE[kind]}", key, table, index, tkey)
        if kind == "error":
            raise ctx.error(f"{what} file {rel!r} cannot be looked up ({detail})", key, table, index, tkey)
        raise ctx.error(f"{what} file {rel!r} not found (looked for {path})", key, table, index, tkey)
    return path


def optional_file(ctx: Ctx, root: Path, doc: dict, table: str, unknown: list[str]) -> Path | None:
    if table not in doc:
        return None
    t = doc[table]
    if not isinstance(t, dict):
        raise ctx.error(f"[{table}] must be a table with a 'file' key", table, table)
    if "file" not in t:
        raise ctx.error(f"missing key 'file' in [{table}]", f"{table}.file", table)
    unknown += [f"{table}.{k}" for k in t if k != "file"]
    return existing_file(ctx, root, t["file"], f"{table}.file", table, table.replace("_", " "))
