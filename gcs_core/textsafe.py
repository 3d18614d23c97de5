"""Strings from files made safe for a terminal: the one sanitiser.

Names, notes and messages that GCS prints come, in the end, from files others wrote
(``mission.toml``, CSV headers, HDF5 attributes, configs). A terminal obeys control
sequences wherever they appear: ``ESC ] 2 ; … BEL`` retitles the window, ``ESC ] 52 ; …``
writes the clipboard, a carriage return overwrites what came before, and the bidi
overrides (U+202E, …) make text read in another order than it is stored.

:func:`terminal_safe` shows every such character escaped, as Python would write it
(``\\x1b``, ``\\x00``, ``\\x9b``, ``\\u202e``), and leaves every other character as it is.
The ``gcs`` command applies it to everything it writes (results, progress lines, log and
error lines), the TUI to the mission name it shows in its status line and titles.
"""

from __future__ import annotations

import re

#: bidi embeddings, overrides and isolates, the marks and the Arabic letter mark: characters
#: that reorder or hide text (Unicode UAX #9; CVE-2021-42574, "Trojan Source").
BIDI = "\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069"
#: C0 controls but tab and newline, DEL, C1 controls, the bidi characters above, and the
#: line and paragraph separators (a line break to some terminals).
_UNSAFE = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029" + BIDI + "]")
_UNSAFE_ONE_LINE = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029" + BIDI + "]")


def _escape(match: re.Match) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def terminal_safe(text: object, *, one_line: bool = False) -> str:
    """``str(text)`` with control, C1 and bidi characters shown escaped (module docstring).

    Tab and newline are kept, unless ``one_line``: then they are escaped too, so that a
    name can never start a new line of its own.
    """
    s = text if isinstance(text, str) else str(text)
    pattern = _UNSAFE_ONE_LINE if one_line else _UNSAFE
    return pattern.sub(_escape, s)


def is_safe(text: str) -> bool:
    """True if :func:`terminal_safe` would leave ``text`` as it is (one-line form)."""
    return _UNSAFE_ONE_LINE.search(text) is None
