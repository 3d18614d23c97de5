"""Converters from foreign formats to a GCS mission directory (ICD §1).

:data:`CONVERTERS` maps a format name to the module that converts it; each module exposes
``convert(source: Path, out: Path, **options) -> ConversionReport``. A new format is one
small module registered here. ``gcs convert FORMAT SOURCE --out DIR`` runs one.

Every converter reads its source by name (columns, datasets), converts units to the
ICD's, keeps every original sample (a start-up transient is flagged and reported, never
cut), writes the source's provenance and licence into the mission directory and refuses
a file that does not match its format with one :class:`~gcs_core.errors.InputError`.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from pathlib import Path

from gcs_core.errors import InputError

#: format name -> module path (each exposes ``convert``)
CONVERTERS: dict[str, str] = {
    "broad": "gcs_core.convert.broad",
}


@dataclass(frozen=True)
class ConversionReport:
    """What a conversion wrote.

    Attributes
    ----------
    out : the mission directory written.
    rows : file (relative to ``out``) -> data rows written.
    transients : one line per flagged start-up transient (kept in the data).
    warnings : one line per other thing the user should know.
    notes : what was estimated or assumed (noise figures, epoch, frames).
    """

    out: Path
    rows: dict[str, int] = field(default_factory=dict)
    transients: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def lines(self) -> list[str]:
        out = [f"mission written to {self.out}"]
        out += [f"  {name}: {n} rows" for name, n in self.rows.items()]
        out += [f"  transient: {t}" for t in self.transients]
        out += [f"  warning: {w}" for w in self.warnings]
        out += [f"  note: {n}" for n in self.notes]
        return out


def convert(fmt: str, source, out, **options) -> ConversionReport:
    """Run the converter of format ``fmt`` (a key of :data:`CONVERTERS`)."""
    if fmt not in CONVERTERS:
        raise InputError(f"unknown format {fmt!r} (known: {', '.join(sorted(CONVERTERS))})",
                         key="format")
    module = importlib.import_module(CONVERTERS[fmt])
    return module.convert(Path(source), Path(out), **options)
