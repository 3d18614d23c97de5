"""The residual-structure search on the two real sample missions (issue 26).

* BROAD 02 (slow rotation): with the effects discovery adds on it, the magnetometer's
  remaining residual follows the measured field's direction in the sensor frame, what
  ``benchmarks/broad_magnetometer_sources.py`` found by hand (a response that depends on
  the field's direction, which a constant calibration cannot hold).
* Astro Pi on the ISS: the report names the channels that are aliases of the orbit phase
  (the Sun angle and the measured field's direction: the station holds LVLH) and of each
  other (the cabin pressure, temperature and light follow a slow trend over the day, time),
  and shows that none of the cabin channels follows the orbit phase.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from repo_paths import ROOT

from gcs_core.config import load_config
from gcs_core.diagnosis.structure_text import report_lines
from gcs_core.session import Analysis

CONFIGS = ROOT / "sample_data" / "configs"


def _analysis(name: str, effects: tuple[str, ...] = ()) -> Analysis:
    cfg = load_config(Path(CONFIGS / name))
    if effects:
        cfg = cfg.with_changes(state={"effects": effects})
    a = Analysis(cfg)
    a.fit(holdout=False)
    return a


@pytest.mark.slow
def test_broad_magnetometer_residual_follows_the_field_direction():
    # what `gcs discover` adds on this sample (docs/case_studies/residual_structure.md)
    a = _analysis(
        "real-broad-02-slow-rotation.toml",
        ("MAG.time_offset", "OPT.time_offset", "MAG.nonorthogonality", "MAG.field_gradient"),
    )
    rep = a.structure()
    mag = [d for d in rep.found if d.sensor == "MAG"]
    assert mag, report_lines(rep)
    assert mag[0].kind == "fov", [(d.component, d.channel) for d in mag]
    assert "MAG.alignment" in mag[0].catalogue  # the linear forms the catalogue has, not significant
    assert any("MAG by follows fov" in line for line in report_lines(rep))


def test_astropi_channels_aliases_of_the_orbit_phase_and_of_each_other():
    a = _analysis("real-astropi-iss.toml")
    rep = a.structure()
    groups = [set(g) for g in rep.alias_groups["MAG"]]
    assert any({"orbit_phase", "sun_angle"} <= g for g in groups), groups
    assert any({"aux:dpressure_hpa", "time"} <= g for g in groups), groups
    r2 = {frozenset((x, y)): v for x, y, v in rep.relations["MAG"]}
    assert r2[frozenset(("aux:dtemp_c", "time"))] > 0.7
    assert r2[frozenset(("aux:dtemp_c", "aux:dpressure_hpa"))] > 0.6
    cabin = ("aux:dtemp_c", "aux:dhumidity_pct", "aux:dpressure_hpa", "aux:light_clear")
    assert not any(frozenset((c, "orbit_phase")) in r2 for c in cabin)  # none follows the orbit
    text = "\n".join(report_lines(rep))
    assert "aliases (R² ≥ 0.9, one stands for the other): orbit phase, sun angle" in text
