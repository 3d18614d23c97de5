"""The documented example config, read from the docstrings that show it.

gcs_core/config.py's module docstring shows every analysis table; the planning tables
(``[trade]``, ``[montecarlo]``) are shown by gcs_core/trade/__init__.py's. Tests parse
the two together, so a documented key that the reader refuses fails a test.
"""

from __future__ import annotations

from gcs_core import config, trade


def docstring_example(doc: str | None) -> str:
    """The indented TOML example after the first ``::`` of a docstring."""
    assert doc, "the docstring holds no example"
    lines = doc.split("::", 1)[1].split("\n")[1:]
    end = next((i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("    ")), len(lines))
    return "\n".join(ln[4:] for ln in lines[:end])


def example_config_text() -> str:
    """Both documented examples as one TOML text."""
    return docstring_example(config.__doc__) + "\n" + docstring_example(trade.__doc__)
