"""Ephemeris ends (issue 11): the models read the orbit a little past a row's time.

A horizon crossing is read up to a spin period after its Sun sighting, so an ephemeris
that ends at the last Sun sighting must be extrapolated by a few seconds; the importer
allows a spin period plus the time-tag bound, says by how much in one warning line, and
refuses only telemetry lying outside the ephemeris by more than that, naming how many
rows and which span.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from gcs_core.config_schema import AnalysisConfig
from gcs_core.errors import InputError
from gcs_core.io.importer import TIME_TAG_BOUND_S, load_mission
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import spinner_nominal
from gcs_core.sim.writer import write_mission

spin_period_s = 6.0  # 10 rpm
noise_floor_bound = 1.1  # normalized RMS of a 40 min fit (≈ 400 spins)


@pytest.fixture(scope="module")
def mission(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ends")
    return write_mission(spinner_nominal(seed=4, duration_s=2400.0), folder / "m")


def _cut_ephemeris(mission, keep):
    """Keep the ephemeris rows for which ``keep(t)`` is true (header kept)."""
    path = mission / "ephemeris.csv"
    lines = path.read_text().splitlines()
    t = np.array([float(x.split(",", 1)[0]) for x in lines[1:]])
    path.write_text("\n".join([lines[0]] + [ln for ln, ti in zip(lines[1:], t) if keep(ti)]) + "\n")
    return t


def _cut_telemetry(mission, t_max):
    """Drop every telemetry row after ``t_max``."""
    for path in (mission / "telemetry").glob("*.csv"):
        lines = path.read_text().splitlines()
        path.write_text("\n".join([lines[0]] + [ln for ln in lines[1:] if float(ln.split(",", 1)[0]) <= t_max]) + "\n")


def _times(path) -> np.ndarray:
    return np.array([float(r.split(",", 1)[0]) for r in path.read_text().splitlines()[1:]])


def test_ephemeris_ending_at_the_last_sun_sighting_is_extrapolated_with_one_warning(mission, tmp_path, caplog):
    import shutil

    m = shutil.copytree(mission, tmp_path / "m")
    # the mission ends at an ephemeris row; its last Sun sighting lies within a spin before it
    t_eph = _times(m / "ephemeris.csv")
    end = float(t_eph[t_eph <= _times(m / "telemetry/PSS1.csv").max()].max())
    _cut_ephemeris(m, lambda t: t <= end)
    _cut_telemetry(m, end)
    assert end - _times(m / "telemetry/PSS1.csv").max() < spin_period_s
    with caplog.at_level("WARNING"):
        imported = load_mission(m)
    warn = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warn) == 1 and list(imported.report.warnings) == warn
    line = warn[0]
    assert "\n" not in line and "past its last row" in line and "HS1" in line
    by = float(re.search(r"up to ([0-9.]+) s past", line).group(1))
    assert 0.0 < by <= spin_period_s + 1.0
    assert imported.ephemeris_margin_s == pytest.approx(spin_period_s + TIME_TAG_BOUND_S, rel=1e-6)
    assert not imported.report.trimmed
    a = Analysis(AnalysisConfig(mission=m), mission=imported)
    res = a.fit(holdout=False)
    assert res.status == "converged"
    assert max(a.rms().values()) <= noise_floor_bound
    assert a.result.residuals["HS1"].n == len(imported.telemetry["HS1"])


def test_rows_needing_more_than_the_margin_are_trimmed_and_counted(mission, tmp_path):
    import shutil

    m = shutil.copytree(mission, tmp_path / "m")
    t_eph = _times(m / "ephemeris.csv")
    e1 = float(t_eph[t_eph <= _times(m / "telemetry/PSS1.csv").max()].max())
    _cut_ephemeris(m, lambda t: t <= e1)
    _cut_telemetry(m, e1 + 9.0)  # the last spin or two lie up to 9 s past the end
    hs = _times(m / "telemetry/HS1.csv")
    imported = load_mission(m)
    # a horizon row past the end needs the orbit more than a spin period + the bound past it
    assert imported.report.trimmed["HS1"] == int(np.count_nonzero(hs > e1)) > 0
    assert any("trimmed" in r and "HS1" in r for r in imported.report.repairs)
    assert float(imported.telemetry["HS1"].t.max()) <= e1


def test_ephemeris_ending_an_hour_early_is_refused_naming_the_span(mission, tmp_path):
    import shutil

    m = shutil.copytree(mission, tmp_path / "m")
    _cut_ephemeris(m, lambda t: t <= 1200.0)
    with pytest.raises(InputError) as err:
        load_mission(m)
    msg = str(err.value)
    assert "\n" not in msg
    n = re.search(r"(\d+) rows of (\w+) \(t = ([0-9.e+]+) to ([0-9.e+]+) s\)", msg)
    assert n, msg
    assert int(n.group(1)) > 100 and float(n.group(3)) > 1200.0 + spin_period_s + TIME_TAG_BOUND_S
    assert "not covered" in msg and "ephemeris" in msg
