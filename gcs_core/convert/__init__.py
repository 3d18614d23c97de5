"""Converters from foreign data formats to a GCS mission directory (ICD §1).

Each format is one module exposing ``convert(source: Path, out: Path, **options) ->
ConversionReport``; :data:`CONVERTERS` maps the format's name to that module, imported
only when used. A converter reads its columns by name, converts units to the ICD's,
keeps every original sample (a sample it would not use is written with ``flag = 1``
and counted, never dropped), writes the data's licence, source and a provenance note
into the mission directory, and refuses a file that does not match with one
:class:`~gcs_core.errors.InputError` naming file, line and column.

A new format is one module here and one line in :data:`CONVERTERS`.
"""

from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass, field
from pathlib import Path

from gcs_core.errors import InputError

__all__ = ["CONVERTERS", "ConversionReport", "convert", "converter"]

#: format name -> module path of its converter (imported lazily)
CONVERTERS: dict[str, str] = {
    "astropi": "gcs_core.convert.astropi",
    "broad": "gcs_core.convert.broad",
}


@dataclass(frozen=True)
class ConversionReport:
    """What a conversion did.

    Attributes
    ----------
    format : the converter's name; source : the file read; out : the mission directory.
    rows : data rows read from the source.
    samples : sensor or file -> samples written (every row, flagged ones included).
    flagged : sensor -> samples written with ``flag = 1`` (kept, not used), e.g. a
        start-up transient.
    files : files written, relative to ``out``.
    notes : one line each: unit conversions, estimates written into the data book,
        what was flagged and why.
    """

    format: str
    source: Path
    out: Path
    rows: int
    samples: dict[str, int] = field(default_factory=dict)
    flagged: dict[str, int] = field(default_factory=dict)
    files: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def lines(self) -> list[str]:
        """A short human-readable account (what ``gcs convert`` prints)."""
        out = [f"{self.format}: {self.rows} rows of {self.source} -> {self.out}"]
        for name, n in self.samples.items():
            extra = f", {self.flagged[name]} flagged" if self.flagged.get(name) else ""
            out.append(f"  {name}: {n} samples{extra}")
        out += [f"  {note}" for note in self.notes]
        out.append("  files: " + ", ".join(self.files))
        return out


def converter(name: str):
    """The converter module of format ``name`` (InputError naming the known formats)."""
    path = CONVERTERS.get(name)
    if path is None:
        raise InputError(f"unknown format {name!r}; known: {', '.join(sorted(CONVERTERS))}", key="format")
    try:
        return importlib.import_module(path)
    except ModuleNotFoundError as err:
        if err.name == path:
            raise InputError(f"the {name!r} converter is not installed ({path})", key="format") from None
        raise


def convert(fmt: str, source, out, **options) -> ConversionReport:
    """Convert ``source`` in format ``fmt`` into the mission directory ``out``.

    Options the format's ``convert`` does not take are dropped when unset (None or False)
    and refused otherwise (e.g. ``--tle`` given to a format that has no orbit).
    """
    func = converter(fmt).convert
    params = inspect.signature(func).parameters
    if not any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        for key in [k for k in options if k not in params]:
            if options[key] is None or options[key] is False:
                del options[key]
            else:
                raise InputError(f"option '{key}' does not apply to the {fmt!r} converter", key=key)
    return func(Path(source), Path(out), **options)
