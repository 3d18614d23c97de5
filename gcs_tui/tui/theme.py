"""Shared colours: read once from ``theme.tcss`` and used by CSS and plots alike.

``theme.tcss`` declares ``$gcs-*`` variables. Textual keeps a variable local to the
file that declares it, so :data:`VARIABLES` parses them here and the app offers them
to every stylesheet (``App.get_theme_variable_defaults``). Plotext takes colours as
RGB tuples: :func:`rgb` converts the same values, so a plot and a table cell for
"edited" are the same orange.
"""

from __future__ import annotations

import re
from pathlib import Path

THEME_TCSS = Path(__file__).with_name("theme.tcss")

_VAR = re.compile(r"^\$(gcs-[\w-]+)\s*:\s*([^;]+);", re.MULTILINE)


def _read_variables(path: Path = THEME_TCSS) -> dict[str, str]:
    return {name: value.strip() for name, value in _VAR.findall(path.read_text(encoding="utf-8"))}


#: ``gcs-*`` variable name -> CSS colour value, from theme.tcss.
VARIABLES: dict[str, str] = _read_variables()


def rgb(name: str) -> tuple[int, int, int]:
    """The ``#rrggbb`` colour of variable ``name`` (``"gcs-edited"``) as an RGB tuple."""
    value = VARIABLES[name].lstrip("#")
    return int(value[0:2], 16), int(value[2:4], 16), int(value[4:6], 16)


#: Colours of successive series in a plot (sensors, elements).
SERIES: tuple[tuple[int, int, int], ...] = (
    (95, 175, 255),
    (255, 175, 0),
    (95, 215, 95),
    (255, 95, 135),
    (175, 135, 255),
    (95, 215, 215),
    (215, 215, 95),
    (255, 135, 0),
    (175, 175, 175),
)


def series(i: int) -> tuple[int, int, int]:
    return SERIES[i % len(SERIES)]


def color(name: str) -> str:
    """The CSS colour of variable ``name`` (for Rich styles in table cells)."""
    return VARIABLES[name]


#: Markers of successive series, so that series differ by shape as well as colour.
MARKERS: tuple[str, ...] = ("●", "■", "▲", "◆", "✚", "✖", "○", "□", "△")


def marker(i: int) -> str:
    return MARKERS[i % len(MARKERS)]
