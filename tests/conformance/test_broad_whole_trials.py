"""The residual-structure search on the whole BROAD trials (issue 26), not only the bundled extract.

Data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC BY 4.0), trials 02
(slow rotation, 186 s) and 09 (fast rotation with breaks) as published in
``../shared/real/broad``; converted whole by ``gcs convert broad`` into the test's folder.

With the catalogue effects ``gcs discover`` adds on these trials (both time offsets, the
magnetometer's non-orthogonality and the lab field's gradient), the report itself must say
what the magnetometer's remaining residual follows, as ``benchmarks/broad_magnetometer_sources.py``
found by hand: the measured field's direction in the sensor frame (a response that depends
on the field's direction, which no constant calibration holds) and, on the fast trial, the
body rate (its time stamps are not its sampling times: an error that grows with the rate).
Skipped when the trials are not beside the checkout.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from repo_paths import ROOT

from gcs_core.config import load_config
from gcs_core.convert.broad import convert
from gcs_core.diagnosis.structure_text import report_lines
from gcs_core.session import Analysis

TRIALS = ROOT.parent / "shared" / "real" / "broad"
CONFIG = ROOT / "sample_data" / "configs" / "real-broad-02-slow-rotation.toml"
#: what discovery adds on the whole trials before the drift families (docs/case_studies/discovery_past_catalogue.md)
ADDED = ("MAG.time_offset", "OPT.time_offset", "MAG.nonorthogonality", "MAG.field_gradient")


def _search(trial: str, tmp: Path):
    source = TRIALS / f"{trial}.hdf5"
    if not source.is_file():
        pytest.skip(f"conformance: needs the BROAD trial {source} (../shared/real/broad beside the checkout)")
    mission = tmp / trial
    convert(source, mission)
    cfg = load_config(CONFIG).with_changes(mission=mission, state={"effects": ADDED})
    a = Analysis(cfg)
    a.fit(holdout=False)
    rep = a.structure()
    return rep, report_lines(rep)


@pytest.mark.slow
def test_slow_rotation_magnetometer_follows_the_field_direction(tmp_path):
    rep, lines = _search("02_undisturbed_slow_rotation_B", tmp_path)
    mag = [d for d in rep.found if d.sensor == "MAG"]
    assert mag and mag[0].kind == "fov", lines
    assert any(line.strip().startswith("MAG b") and "follows fov" in line for line in lines), lines


@pytest.mark.slow
def test_fast_rotation_magnetometer_follows_the_field_direction_and_the_rate(tmp_path):
    rep, lines = _search("09_undisturbed_fast_rotation_with_breaks_B", tmp_path)
    kinds = {d.kind for d in rep.found if d.sensor == "MAG"}
    assert "fov" in kinds, lines
    assert any(d.sensor == "MAG" and d.channel.startswith("rate") for d in rep.found), lines
