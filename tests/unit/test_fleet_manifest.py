"""The fleet manifest: a bad key is one line naming it (exit 2), before any work; the report's
fleet statistics and its HTML page on synthetic calibrations (no fit, no cluster)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from gcs_core.errors import ConfigError
from gcs_core.fleet.html import render_html
from gcs_core.fleet.manifest import read_manifest
from gcs_core.fleet.report import MAD_TO_SIGMA, _distributions, _moved
from gcs_core.io.scds import ScdsVersion
from gcs_tui.cli.commands import main

GOOD = """
[fleet]
name = "t"
days = ["d1", "d2"]
output = "out"

[template.analysis]
method = "batch"
[template.verification]
requirement_deg = 0.05

[[spacecraft]]
name = "A"
data = "data/A/{day}"

[[spacecraft]]
name = "B"
data = "data/B/{day}"
[spacecraft.config.filter]
edit_k = 4.0
"""


def _write(tmp_path, text):
    p = tmp_path / "fleet.toml"
    p.write_text(text)
    return p


def test_a_good_manifest_resolves_each_spacecraft_config(tmp_path):
    m = read_manifest(_write(tmp_path, GOOD))
    assert m.days == ("d1", "d2") and [s.name for s in m.spacecraft] == ["A", "B"]
    a, b = m.config(m.spacecraft[0], "d2"), m.config(m.spacecraft[1], "d1")
    assert a.method == b.method == "batch"
    assert a.verification.requirement_deg == 0.05
    assert b.filter.edit_k == 4.0 and a.filter.edit_k != 4.0
    assert a.mission == (tmp_path / "data/A/d2").resolve()
    assert m.output == (tmp_path / "out").resolve()


@pytest.mark.parametrize(
    "edit, key",
    [
        (lambda t: t.replace('name = "t"', 'name = "t"\ncolour = 1'), "fleet.colour"),
        (lambda t: t.replace('days = ["d1", "d2"]', "days = []"), "fleet.days"),
        (lambda t: t.replace('days = ["d1", "d2"]', 'days = ["d1", "d1"]'), "fleet.days"),
        (lambda t: t.replace('method = "batch"', 'method = "fast"'), "template.analysis.method"),
        (lambda t: t.replace("edit_k = 4.0", "edit_k = -1.0"), "spacecraft[B].config.filter.edit_k"),
        (lambda t: t.replace("edit_k = 4.0", "edit_kk = 4.0"), "spacecraft[B].config.filter.edit_kk"),
        (lambda t: t.replace('data = "data/A/{day}"', ""), "spacecraft[A].data"),
        (lambda t: t.replace('name = "B"', 'name = "A"'), "spacecraft[2].name"),
        (lambda t: t + "\n[extra]\n", "extra"),
    ],
)
def test_a_bad_manifest_is_one_line_naming_the_key(tmp_path, edit, key):
    p = _write(tmp_path, edit(GOOD))
    with pytest.raises(ConfigError) as err:
        read_manifest(p)
    assert err.value.key == key
    assert str(p) in str(err.value)


def test_gcs_fleet_on_a_bad_manifest_exits_2_with_one_line(tmp_path, capsys):
    p = _write(tmp_path, GOOD.replace("edit_k = 4.0", "edit_k = -1.0"))
    assert main(["fleet", str(p), "--progress", "off"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "spacecraft[B].config.filter.edit_k" in err and str(p) in err
    assert "Traceback" not in err


def _version(n, params, models=None, status="converged"):
    prov = {"models": models or {"TAM1": "magnetometer"}, "solve_for": list(params), "status": status}
    return ScdsVersion(n, {k: (x, s, "nT") for k, (x, s) in params.items()}, tuple(params), None, prov)


def test_moved_is_the_change_in_its_combined_sigma():
    old = _version(1, {"TAM1.bias_x": (0.0, 3.0), "TAM1.bias_y": (0.0, 3.0)})
    new = _version(2, {"TAM1.bias_x": (30.0, 4.0), "TAM1.bias_y": (10.0, 4.0)})
    moved = _moved(new, old, 3.0)
    assert [m["element"] for m in moved] == ["TAM1.bias_x"]  # 30/5 = 6σ; 10/5 = 2σ is not
    assert moved[0]["z"] == pytest.approx(6.0)


def test_outliers_are_named_against_the_fleets_robust_spread():
    rng = np.random.default_rng(25)
    latest = {f"SC{i:02d}": _version(1, {"TAM1.bias_x": (float(rng.normal(0, 5.0)), 1.0)}) for i in range(20)}
    latest["SC99"] = _version(1, {"TAM1.bias_x": (90.0, 1.0)})  # ~18 spreads out
    d = _distributions(latest, 5.0)["magnetometer"]["bias_x"]
    assert d["outliers"] == ["SC99/TAM1"]
    xs = np.array([v["value"] for v in d["values"]])
    mad = np.median(np.abs(xs - np.median(xs)))
    assert d["robust_sigma"] == pytest.approx(MAD_TO_SIGMA * mad)
    assert d["n"] == 21


def test_the_html_page_is_self_contained_and_escapes_names():
    report = {
        "fleet": "<b>x</b>",
        "manifest": "m.toml",
        "generated_utc": "2026-01-01T00:00:00Z",
        "days": ["d1", "d2"],
        "moved_sigma": 3.0,
        "outlier_sigma": 5.0,
        "spacecraft": [{"name": "A", "days": [{"day": "d1", "state": "error", "error": "f.csv:3:2: <bad>"}]}],
        "errors": [{"spacecraft": "A", "day": "d1", "error": "f.csv:3:2: <bad>"}],
        "moved": [],
        "discovered": [],
        "distributions": {},
        "trends": {"TAM1.bias_x": {"unit": "nT", "series": {"A": [["d1", 1.0, 0.5], ["d2", 2.0, 0.5]]}}},
    }
    page = render_html(report)
    assert "<b>x</b>" not in page and "&lt;b&gt;x&lt;/b&gt;" in page
    assert "<script" not in page and not re.search(r"(src|href)=", page)
    assert re.findall(r"https?://[^\"']+", page) == ["http://www.w3.org/2000/svg"]  # the SVG namespace only
    assert page.count("<svg") == 1 and "<polyline" in page


def test_a_summary_with_non_finite_numbers_is_stored_as_strict_json():
    from gcs_core.fleet.task import _plain

    assert _plain({"a": [1.0, float("nan")], "b": {"c": float("inf")}, "d": "x"}) == {
        "a": [1.0, None],
        "b": {"c": None},
        "d": "x",
    }
