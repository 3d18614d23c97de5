"""CSV tables of the mission directory, read and written per ICD §1.

The rules a file must keep (ICD §1):

* comma separated, UTF-8; optional ``#`` comment lines (and blank lines) anywhere;
* one header line of column names, then data rows sorted by time;
* ``t`` is seconds since the mission epoch; extra columns are allowed and kept;
* an empty field or ``nan`` drops that row (the sample), counted in
  :attr:`Table.dropped_nan`;
* an exact duplicate of the previous row (a packet received twice) is dropped,
  counted in :attr:`Table.dropped_duplicates`;
* two different rows with the same time, times going backwards, a missing required
  column, text that is not a number, an infinite value or a row with the wrong number
  of fields are refused with :class:`~gcs_core.errors.InputError` naming the file, the
  1-based line and the column (number and name).

Speed: the data rows are parsed in bulk by numpy's C reader (``np.loadtxt``);
600 000 rows of four columns take well under two seconds. Only when the bulk parse
refuses a file does a line-by-line pass run, to find and name the first bad field.
"""

from __future__ import annotations

import logging
import os
import re
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from gcs_core.errors import InputError
from gcs_core.fileperm import atomic_open
from gcs_core.inputs import refuse_unreadable
from gcs_core.io.types import Table

log = logging.getLogger(__name__)

#: what a number may look like (decimal, optional exponent, nan/inf); ASCII only.
_NUMBER = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf|infinity|nan)", re.IGNORECASE)
_NAN_WORDS = frozenset({"", "nan", "+nan", "-nan"})
#: numpy's complaint about an empty (or blank) field.
_EMPTY_FIELD_ERR = re.compile(r"could not convert string '\s*' to")
#: a field that is empty or blank, to be read as NaN (multiline text).
_EMPTY_FIELD = re.compile(r"(^|,)[ \t\r]*(?=,|$)", re.MULTILINE)
#: an empty or blank field, anywhere in a block of lines (the fast path declines it).
_EMPTY_FIELD_FAST = re.compile(r"(?:^|,)[ \t\r]*(?:,|$)", re.MULTILINE)
#: a line holding nothing but blanks (inside the data rows).
_BLANK_LINE = re.compile(r"\n[ \t\r\f\v]*(?:\n|$)")  # searched in "\n" + text
_SHOW = 30  # characters of a bad field quoted in a message


def _quote(text: str) -> str:
    text = text.strip()
    return repr(text if len(text) <= _SHOW else text[:_SHOW] + "...")


def _decode(raw: bytes, path: Path) -> str:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        before = raw[: err.start]
        line = before.count(b"\n") + 1
        line_start = before.rfind(b"\n") + 1
        column = raw[line_start : err.start].count(b",") + 1
        raise InputError(f"not UTF-8 text (byte 0x{raw[err.start]:02x})", file=path, line=line, column=column) from None
    return text[1:] if text.startswith("\ufeff") else text


def _parse_header(line: str, lineno: int, path: Path, required: tuple[str, ...], what: str) -> list[str]:
    names = [n.strip() for n in line.split(",")]
    if all(_NUMBER.fullmatch(n) for n in names):
        raise InputError(
            "no header line: the first line holds numbers, not column names "
            f"(ICD §1; {what} needs {', '.join(required)})",
            file=path,
            line=lineno,
            column=1,
        )
    seen: dict[str, int] = {}
    for k, name in enumerate(names, start=1):
        if not name:
            raise InputError(f"empty column name in the header (column {k})", file=path, line=lineno, column=k)
        if name in seen:
            raise InputError(
                f"column name '{name}' appears twice in the header (columns {seen[name]} and {k})",
                file=path,
                line=lineno,
                column=k,
            )
        seen[name] = k
    for name in required:
        if name not in seen:
            raise InputError(
                f"missing required column '{name}' ({what} needs {', '.join(required)})",
                file=path,
                line=lineno,
                column=name,
            )
    return names


def _field_error(path: Path, lineno: int, k: int, names: list[str], message: str) -> InputError:
    return InputError(f"{message} in column {k + 1} '{names[k]}'", file=path, line=lineno, column=k + 1)


def _parse_slowly(rows: list[str], linenos: list[int], names: list[str], path: Path) -> np.ndarray:
    """Line-by-line parse, raising at the first bad field (file order)."""
    ncol = len(names)
    out = np.empty((len(rows), ncol))
    for i, (row, lineno) in enumerate(zip(rows, linenos)):
        fields = row.split(",")
        if len(fields) < ncol:
            k = len(fields)
            raise InputError(
                f"{len(fields)} fields where the header has {ncol}: missing column {k + 1} '{names[k]}'",
                file=path,
                line=lineno,
                column=k + 1,
            )
        if len(fields) > ncol:
            raise InputError(
                f"{len(fields)} fields where the header has {ncol} columns", file=path, line=lineno, column=ncol + 1
            )
        for k, field in enumerate(fields):
            s = field.strip()
            if s.lower() in _NAN_WORDS:
                out[i, k] = np.nan
                continue
            if not (s.isascii() and _NUMBER.fullmatch(s)):
                raise _field_error(path, lineno, k, names, f"not a number: {_quote(s)}")
            value = float(s)
            if np.isinf(value):
                raise _field_error(path, lineno, k, names, "infinite value")
            out[i, k] = value
    return out


def _parse_bulk(rows: list[str], linenos: list[int], names: list[str], path: Path) -> np.ndarray:
    """numpy's C reader; on refusal, the slow pass names the place."""
    ncol = len(names)
    if not rows:
        return np.zeros((0, ncol))
    try:
        try:
            data = np.loadtxt(rows, delimiter=",", comments=None, dtype=np.float64, ndmin=2)
        except ValueError as err:
            if not _EMPTY_FIELD_ERR.search(str(err)):
                raise
            # empty fields mean NaN (ICD §1): spell them out and parse again
            filled = _EMPTY_FIELD.sub(r"\1nan", "\n".join(rows)).split("\n")
            data = np.loadtxt(filled, delimiter=",", comments=None, dtype=np.float64, ndmin=2)
        if data.shape != (len(rows), ncol):
            raise ValueError("shape")
    except ValueError:
        log.debug("%s: bulk parse refused, locating the error line by line", path)
        return _parse_slowly(rows, linenos, names, path)
    inf = np.isinf(data)
    if inf.any():
        i, k = np.argwhere(inf)[0]
        raise _field_error(path, linenos[i], int(k), names, "infinite value")
    return data


def _header(text: str, path: Path, required: tuple[str, ...], what: str):
    """The header line, found without splitting the file: ``(names, header_at, eol)``, the
    0-based index of the header line and the offset of the newline that ends it."""
    pos, header_at, n = 0, 0, len(text)
    while pos < n:  # the first non-comment, non-blank line
        eol = text.find("\n", pos)
        eol = n if eol < 0 else eol
        stripped = text[pos:eol].strip()
        if stripped and not stripped.startswith("#"):
            names = _parse_header(text[pos:eol].rstrip("\r"), header_at + 1, path, required, what)
            return names, header_at, eol
        pos, header_at = eol + 1, header_at + 1
    raise InputError(f"empty file: no header line ({what} needs {', '.join(required)})", file=path)


def _split_lines(text: str, header_at: int, eol: int):
    """Data rows after the header and their 1-based line numbers (comments and blank
    lines skipped)."""
    body = text[eol + 1 :].split("\n")
    while body and not body[-1].strip():
        body.pop()  # trailing newline(s)
    first = header_at + 2  # line number of the first body line
    joined = "\n".join(body)
    if "#" not in joined and not _BLANK_LINE.search("\n" + joined):  # the usual case: no skips
        return body, list(range(first, first + len(body)))
    rows, linenos = [], []
    for i, line in enumerate(body):
        s = line.strip()
        if not s or s[0] == "#":
            continue
        rows.append(line)
        linenos.append(first + i)
    return rows, linenos


def read_table(path: str | os.PathLike, *, required: Iterable[str] = ("t",), what: str = "telemetry") -> Table:
    """Read one CSV file of the mission directory (ICD §1).

    Parameters
    ----------
    path : the CSV file.
    required : columns that must be present; ``t`` is always required.
    what : what the file is, for messages ("telemetry", "ephemeris", ...).

    Returns
    -------
    Table with every column as a float64 (N,) array, rows with empty/NaN fields and
    exact duplicate rows dropped (and counted), ``t`` strictly increasing.

    Raises
    ------
    InputError naming file, line and column for any breach of ICD §1.
    """
    path = Path(path)
    required = ("t",) + tuple(c for c in required if c != "t")
    refuse_unreadable(path, f"{what} file")  # a FIFO would block, /dev/zero never end
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{what} file not found", file=path) from None
    except IsADirectoryError:
        raise InputError(f"{what} file is a directory", file=path) from None
    except OSError as err:
        raise InputError(f"cannot read {what} file ({err.strerror})", file=path) from None
    text = _decode(raw, path)
    if "\x00" in text:
        lineno = text[: text.index("\x00")].count("\n") + 1
        raise InputError("NUL byte in a text file (binary data?)", file=path, line=lineno)
    del raw
    names, header_at, eol = _header(text, path, required, what)
    fast = _read_plain(path, text, names, header_at, eol)
    if fast is not None:
        return _finish(path, names, *fast)
    rows, linenos = _split_lines(text, header_at, eol)
    data = _parse_bulk(rows, linenos, names, path)
    lines = np.asarray(linenos, dtype=np.int64)
    return _finish(path, names, data, lines)


_TRAILING_BLANKS = " \t\r\n\f\v"


def _read_plain(path: Path, text: str, names: list[str], header_at: int, eol: int):
    """The usual file, read without holding its lines as Python strings.

    A file whose data rows hold no comment, no blank line and no empty field is parsed by
    numpy's C reader straight from the file, in chunks: the memory it needs is the
    result's, not several times the text's (a week of 1 Hz telemetry stays flat). Returns
    ``(data, line numbers)``, or None when the file needs the general path (which also
    finds and names any bad field).
    """
    n = len(text)
    end = n
    while end > eol and text[end - 1] in _TRAILING_BLANKS:
        end -= 1
    if end <= eol + 1:
        return np.zeros((0, len(names))), np.zeros(0, np.int64)
    body_start = eol + 1
    # comments, blank lines, empty fields (NaN) and a lone CR (a line break to the C
    # reader, not to the ICD) take the general path
    if (
        text.find("#", body_start, end) >= 0
        or text.count("\r", body_start, end) != text.count("\r\n", body_start, end)
        or _BLANK_LINE.search(text, eol, end)
        or _EMPTY_FIELD_FAST.search(text, body_start, end)
    ):
        return None
    rows = text.count("\n", body_start, end) + 1
    try:
        data = np.loadtxt(
            path,
            delimiter=",",
            comments=None,
            skiprows=header_at + 1,
            max_rows=rows,
            dtype=np.float64,
            ndmin=2,
            encoding="utf-8",
        )
    except (ValueError, OSError):
        return None
    if data.shape != (rows, len(names)):
        return None
    inf = np.isinf(data)
    if inf.any():
        i, k = np.argwhere(inf)[0]
        raise _field_error(path, int(header_at + 2 + i), int(k), names, "infinite value")
    return data, np.arange(header_at + 2, header_at + 2 + rows, dtype=np.int64)


def _finish(path: Path, names: list[str], data: np.ndarray, lines: np.ndarray) -> Table:
    """Drop NaN rows and duplicates, check time order, build the Table."""
    kt = names.index("t")
    nan_rows = np.isnan(data).any(axis=1)
    dropped_nan = int(nan_rows.sum())
    if dropped_nan:
        data, lines = data[~nan_rows], lines[~nan_rows]
    t = data[:, kt]
    dt = np.diff(t)
    back = np.flatnonzero(dt < 0)
    same = np.flatnonzero(dt == 0)
    conflict = same[~np.all(data[same + 1] == data[same], axis=1)] if same.size else same
    first_back = back[0] if back.size else None
    first_conflict = conflict[0] if conflict.size else None
    if first_back is not None and (first_conflict is None or first_back <= first_conflict):
        i = first_back + 1
        raise InputError(
            f"time {t[i]:.9g} is earlier than {t[i - 1]:.9g} on line "
            f"{lines[i - 1]}: rows must be sorted by time in column {kt + 1} 't'",
            file=path,
            line=int(lines[i]),
            column=kt + 1,
        )
    if first_conflict is not None:
        i = first_conflict + 1
        diff = int(np.flatnonzero(data[i] != data[i - 1])[0])
        raise InputError(
            f"two different rows with the same time t = {t[i]:.9g} (lines "
            f"{lines[i - 1]} and {lines[i]} differ in column {diff + 1} "
            f"'{names[diff]}')",
            file=path,
            line=int(lines[i]),
            column=diff + 1,
        )
    dropped_dup = int(same.size)
    if dropped_dup:
        keep = np.ones(len(t), dtype=bool)
        keep[same + 1] = False
        data, lines = data[keep], lines[keep]
    # one array per column: a view into a shared block would keep every column alive
    # as long as any one of them is held
    columns = {name: np.array(data[:, k]) for k, name in enumerate(names)}
    del data
    return Table(
        path=path, t=columns["t"], columns=columns, lines=lines, dropped_nan=dropped_nan, dropped_duplicates=dropped_dup
    )


def write_table(
    path: str | os.PathLike, columns: Mapping[str, np.ndarray], *, comments: Iterable[str] = (), fmt: str = "%.17g"
) -> Path:
    """Write a CSV file readable by :func:`read_table`, atomically.

    Parameters
    ----------
    path : destination; written to a temporary file in the same directory, flushed,
        synced and renamed over ``path`` (a crash leaves the old file or the new one).
    columns : name -> (N,) array, in the order of the header; ``t`` should come first.
    comments : lines written first, each prefixed with ``# ``.
    fmt : printf format of every value (``%.17g`` round-trips float64 exactly).
    """
    path = Path(path)
    names = list(columns)
    if not names:
        raise ValueError("write_table needs at least one column")
    for name in names:
        if not name or "," in name or "\n" in name or name != name.strip():
            raise ValueError(f"bad column name {name!r}")
    arrays = [np.asarray(columns[n], dtype=np.float64).reshape(-1) for n in names]
    n = {a.shape[0] for a in arrays}
    if len(n) != 1:
        raise ValueError(f"columns have different lengths: {sorted(n)}")
    data = np.column_stack(arrays) if arrays[0].size else np.zeros((0, len(names)))
    with atomic_open(path, "w", newline="\n") as fh:
        for c in comments:
            for part in str(c).splitlines() or [""]:
                fh.write(f"# {part}\n")
        fh.write(",".join(names) + "\n")
        if data.shape[0]:
            np.savetxt(fh, data, fmt=fmt, delimiter=",")
    return path
