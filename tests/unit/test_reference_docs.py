"""The reference's examples run: the Python API's worked example (docs/reference/python_api.md)
prints what its comments say, and the JSON report it writes has no field that
docs/reference/report.md does not list."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re

import pytest
from repo_paths import ROOT

API = ROOT / "docs" / "reference" / "python_api.md"
REPORT_DOC = ROOT / "docs" / "reference" / "report.md"


def example_code() -> str:
    m = re.search(r"```python\n(.*?)```", API.read_text(), re.DOTALL)
    assert m, "docs/reference/python_api.md has no ```python block"
    return m.group(1)


def expected_prints(code: str) -> list[str | None]:
    """The comment beside each print (None where it says only ≈)."""
    out = []
    for line in code.splitlines():
        if line.startswith("print("):
            comment = line.split("  # ", 1)[1].strip()
            out.append(None if comment.startswith("≈") else comment)
    return out


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """Run the example in a scratch folder that sees the repository's sample_data."""
    work = tmp_path_factory.mktemp("api")
    (work / "sample_data").symlink_to(ROOT / "sample_data")
    code = example_code()
    here = os.getcwd()
    stdout = io.StringIO()
    os.chdir(work)
    try:
        with contextlib.redirect_stdout(stdout):
            exec(compile(code, str(API), "exec"), {"__name__": "example"})
    finally:
        os.chdir(here)
    return code, stdout.getvalue().splitlines(), json.loads((work / "out" / "report.json").read_text())


def test_the_api_example_prints_what_it_says(ran):
    code, printed, _ = ran
    expected = expected_prints(code)
    assert len(printed) == len(expected)
    for got, want in zip(printed, expected, strict=True):
        if want is not None:
            assert got == want


def test_the_example_finds_the_answer(ran):
    _, _, report = ran
    answer = json.loads((ROOT / "sample_data" / "answers" / "hidden-tam-contamination.json").read_text())
    assert [s["added"] for s in report["steps"]] == [e["id"] for e in answer["hidden_effects"]]


def documented(section: str | None = None) -> set[str]:
    text = REPORT_DOC.read_text()
    if section is not None:
        text = text.split(f"## `{section}`", 1)[1].split("\n## ", 1)[0]
    return set(re.findall(r"`([a-z_0-9]+)(?:\.<[a-z]+>)?`", text))


def test_every_report_field_is_documented(ran):
    _, _, report = ran
    missing = set(report) - documented()
    assert not missing, f"add to docs/reference/report.md: {sorted(missing)}"
    rows = {
        "sensors.<name>": [row for row in report["sensors"].values()],
        "state[]": report["state"],
        "candidates[]": report["candidates"],
        "steps[]": report["steps"],
        "goodness_of_fit": [report["goodness_of_fit"]],
        "remaining.<name>": list(report["remaining"].values()),
        "sigma_scale": [report["sigma_scale"]],
    }
    for section, items in rows.items():
        keys = set().union(*(set(r) for r in items)) if items else set()
        missing = keys - documented(section)
        assert not missing, f"add to docs/reference/report.md, section {section}: {sorted(missing)}"
