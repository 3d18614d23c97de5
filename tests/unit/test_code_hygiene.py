"""Every silenced lint or type finding says which one and why, in place.

ruff (``RUF100``) and mypy (``warn_unused_ignores``) already refuse a ``noqa`` or a
``type: ignore`` that silences nothing; this adds that each names its code and gives a reason.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FOLDERS = ("gcs_core", "gcs_tui", "tests", "benchmarks")

#: a noqa comment: its codes (CODE[, CODE]), then a dash and the reason
NOQA = re.compile(r"#\s*" + "noqa" + r"\b(?P<codes>:\s*[A-Z]+[0-9]+(?:\s*,\s*[A-Z]+[0-9]+)*)?(?P<rest>.*)$")
#: a type-ignore comment: its codes in brackets, then a comment with the reason
IGNORE = re.compile(r"#\s*type:\s*" + "ignore" + r"(?P<codes>\[[a-z-]+(?:,\s*[a-z-]+)*\])?(?P<rest>.*)$")


def _comments():
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            if path.name == Path(__file__).name:
                continue
            for lineno, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
                yield f"{path.relative_to(ROOT)}:{lineno}", line


def test_each_noqa_names_its_code_and_why():
    bad = []
    for where, line in _comments():
        m = NOQA.search(line)
        if m:
            reason = m.group("rest").strip(" —-:")
            if not m.group("codes") or len(reason.split()) < 2:
                bad.append(where)
    assert not bad, "a noqa without its code or a reason: " + ", ".join(bad)


def test_each_type_ignore_names_its_code_and_why():
    bad = []
    for where, line in _comments():
        m = IGNORE.search(line)
        if m:
            reason = m.group("rest").strip(" #")
            if not m.group("codes") or len(reason.split()) < 2:
                bad.append(where)
    assert not bad, "a type: ignore without its code or a reason: " + ", ".join(bad)
