"""Tables whose column widths are measured once, here, from every cell.

A :class:`~textual.widgets.DataTable` measures new rows when it next goes idle; a table
rebuilt while a background job finishes has been seen drawn at its header widths (every
number cut). :func:`fill` measures the cells itself and gives each column its width.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from rich.text import Text
from textual.coordinate import Coordinate
from textual.widgets import DataTable


def _width(cell) -> int:
    return (cell if isinstance(cell, Text) else Text(str(cell))).cell_len


def cursor_key(table: DataTable) -> str:
    """The key :func:`fill` gave the row under the cursor (the table has rows)."""
    return str(table.coordinate_to_cell_key(Coordinate(table.cursor_row, 0)).row_key.value)


def fill(table: DataTable, labels: Sequence, rows: Iterable[tuple[Sequence, str | None]]) -> None:
    """Clear ``table`` and fill it: ``labels`` the column headers, ``rows`` ``(cells, key)``."""
    rows = list(rows)
    table.clear(columns=True)
    for j, label in enumerate(labels):
        w = max([_width(label)] + [_width(cells[j]) for cells, _ in rows if j < len(cells)])
        table.add_column(label, width=w)
    for cells, key in rows:
        table.add_row(*cells, key=key)
