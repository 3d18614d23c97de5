"""What every converter needs: reading columns by name, writing ICD files, staging the
mission directory atomically, and two small estimates from the data itself.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import math
import os
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from gcs_core.errors import InputError
from gcs_core.fileperm import atomic_directory

__all__ = [
    "NamedCsv",
    "read_named_csv",
    "write_csv",
    "staged_directory",
    "check_destination",
    "MARKER",
    "sha256",
    "leading_transient",
]


class NamedCsv:
    """A CSV file read as text, its columns looked up by name.

    Attributes
    ----------
    path : the file; header : column names; rows : list of fields per data row;
    lines : 1-based file line of each row.
    """

    def __init__(self, path: Path, header: list[str], rows: list[list[str]], lines: list[int]):
        self.path, self.header, self.rows, self.lines = path, header, rows, lines

    def __len__(self) -> int:
        return len(self.rows)

    def index(self, name: str) -> int:
        try:
            return self.header.index(name)
        except ValueError:
            raise InputError(
                f"missing column '{name}' (the file has: {', '.join(self.header)})", file=self.path, line=1, column=name
            ) from None

    def text(self, name: str) -> list[str]:
        """The raw fields of column ``name``."""
        j = self.index(name)
        return [row[j] for row in self.rows]

    def numbers(self, name: str) -> np.ndarray:
        """Column ``name`` as floats; a field that is not a finite number is refused with
        its line and column (1-based character position of the field)."""
        j = self.index(name)
        out = np.empty(len(self.rows))
        for k, row in enumerate(self.rows):
            field = row[j]
            try:
                value = float(field)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                col = sum(len(f) + 1 for f in row[:j]) + 1
                raise InputError(
                    f"column '{name}': {field.strip()!r} is not a number",
                    file=self.path,
                    line=self.lines[k],
                    column=col,
                )
            out[k] = value
        return out

    def error(self, k: int, name: str, message: str) -> InputError:
        """An InputError at row ``k``'s line, at column ``name``."""
        j = self.index(name)
        col = sum(len(f) + 1 for f in self.rows[k][:j]) + 1
        return InputError(f"column '{name}': {message}", file=self.path, line=self.lines[k], column=col)


def read_named_csv(path: Path, required: Sequence[str]) -> NamedCsv:
    """Read a comma-separated file with one header line; check ``required`` columns exist
    and every row has as many fields as the header."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            rows, lines = [], []
            header = None
            for row in reader:
                if not row or all(not f.strip() for f in row):
                    continue
                if header is None:
                    header = [h.strip() for h in row]
                    continue
                if len(row) != len(header):
                    raise InputError(
                        f"{len(row)} fields where the header has {len(header)}", file=path, line=reader.line_num
                    )
                rows.append(row)
                lines.append(reader.line_num)
    except OSError as err:
        raise InputError(f"cannot read the file ({err.strerror})", file=path) from None
    except UnicodeDecodeError as err:
        raise InputError(f"not UTF-8 text ({err.reason})", file=path) from None
    except csv.Error as err:
        raise InputError(f"not a CSV file ({err})", file=path) from None
    if header is None:
        raise InputError("empty file: no header line", file=path)
    table = NamedCsv(Path(path), header, rows, lines)
    for name in required:
        table.index(name)
    if not rows:
        raise InputError("no data rows after the header", file=path, line=1)
    return table


def write_csv(
    path: Path,
    header: Sequence[str],
    columns: Sequence[np.ndarray],
    formats: Sequence[str],
    comments: Sequence[str] = (),
) -> None:
    """Write an ICD CSV file (``# comment`` lines, a header, one row per sample)."""
    n = len(columns[0])
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        for c in comments:
            fh.write(f"# {c}\n")
        fh.write(",".join(header) + "\n")
        fmt = ",".join(formats) + "\n"
        cols = [np.asarray(c) for c in columns]
        for i in range(n):
            fh.write(fmt % tuple(c[i] for c in cols))


#: the file every converted mission directory carries: ``--force`` replaces only such a one.
MARKER = ".gcs-converted"


def check_source(source: Path, fmt: str) -> None:
    """The source is a regular file (a FIFO would block, ``/dev/zero`` never end)."""
    from gcs_core.inputs import refuse_unreadable

    kind = refuse_unreadable(source, f"{fmt} source")
    if kind != "file":
        raise InputError(f"{fmt} source {'is a directory, not a file' if kind == 'dir' else 'not found'}", file=source)


def check_destination(source: Path | None, out: Path, *, overwrite: bool) -> Path:
    """Check the mission directory to write before any work; returns it, links resolved.

    Refused: a path that is not a directory; a non-empty directory without ``overwrite``;
    with it, a directory GCS did not convert (no :data:`MARKER` file), one holding the
    source file or the current directory, or the root of the file system.
    """
    shown = Path(out)
    out = Path(os.path.realpath(out))
    if shown.exists() and not shown.is_dir():
        raise InputError("the output exists and is not a directory", file=shown)
    src = Path(os.path.realpath(source)) if source is not None else None
    if src is not None and (out == src or out in src.parents):
        raise InputError(f"the output directory holds the source {source}: choose another folder", file=shown)
    if out.is_dir() and any(out.iterdir()):
        if not overwrite:
            raise InputError("the output directory is not empty (give --force to replace it)", file=shown)
        if out.parent == out or out == Path(os.path.realpath(os.getcwd())) or out in Path(os.getcwd()).parents:
            raise InputError("the output directory holds the current directory: choose another folder", file=shown)
        if not (out / MARKER).is_file():
            raise InputError(
                f"the output directory was not made by gcs convert (no {MARKER} file): --force replaces "
                "only a converted mission directory; choose a new folder",
                file=shown,
            )
    return out


@contextlib.contextmanager
def staged_directory(out: Path, *, overwrite: bool = False, source: Path | None = None) -> Iterator[Path]:
    """Yield an empty directory next to ``out``; on success it replaces ``out``
    (:func:`gcs_core.fileperm.atomic_directory`: its files synced, one rename).

    ``out`` is checked by :func:`check_destination` (``--force`` replaces only a directory
    GCS converted, never one holding the source); the new directory carries
    :data:`MARKER` and gets the usual permissions (the umask applies). On failure the
    staging directory is removed and ``out`` is untouched.
    """
    out = check_destination(source, Path(out), overwrite=overwrite)
    with atomic_directory(out) as stage:
        yield stage
        (stage / MARKER).write_text(
            "This mission directory was written by gcs convert; gcs convert --force may replace it.\n",
            encoding="utf-8",
        )


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def leading_transient(
    y: np.ndarray, sigma: np.ndarray, *, t: np.ndarray | None = None, window: int = 12, k: float = 3.0
) -> int:
    """Number of leading samples of a start-up transient (a settle, e.g. from zero).

    Two passes. (1) The settle is steep at first: it lasts at least until the first
    sample ``s`` from which the normalized second differences ``|d_i|/(√6 σ)`` stay within
    ``k`` on every axis for ``window`` differences. (2) Its tail can be smaller than the
    noise of a second difference yet larger than ``σ``: a quadratic in time, fitted per axis
    to the ``3 window`` samples after ``s + window``, is extrapolated back, and the transient
    extends over the samples from ``s`` on that lie more than ``k σ`` from it on some axis.
    Samples ``0 .. n−1`` are the transient; 0 when the data start steady.
    """
    y = np.asarray(y, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    t = np.arange(len(y), dtype=float) if t is None else np.asarray(t, dtype=float)
    d = y[2:] - 2.0 * y[1:-1] + y[:-2]
    z = np.max(np.abs(d) / (math.sqrt(6.0) * sigma), axis=1)
    quiet = z <= k
    s = next((i for i in range(len(z) - window + 1) if np.all(quiet[i : i + window])), None)
    if s is None:
        return 0
    ref = slice(s + window, s + 4 * window)
    if t[ref].size < 3 * window:
        return s
    tc = t[ref] - t[s]
    coef = np.polynomial.polynomial.polyfit(tc, y[ref], 2)  # (3, m)
    e = s
    while e < ref.start:
        fit = np.polynomial.polynomial.polyval(t[e] - t[s], coef)
        if np.all(np.abs(y[e] - fit) <= k * sigma):
            break
        e += 1
    return e
