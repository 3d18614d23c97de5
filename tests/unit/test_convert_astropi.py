"""``gcs convert astropi``: a small extract of the real file, and files that do not match.

The extract (``tests/data/astropi/``) is the header and first 80 rows of the Raspberry Pi
Foundation's Astro Pi Mark II commissioning data (CC BY-SA 4.0, see SOURCE.md there):
it holds the unit's start-up transient, the field settling from 12.7 µT to 35 µT in
about 25 s, then wandering by several σ for about a minute more.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from repo_paths import TEST_DATA

from gcs_core.convert import CONVERTERS, convert, converter
from gcs_core.convert.astropi import procrustes_mounting
from gcs_core.convert.common import leading_transient
from gcs_core.errors import InputError
from gcs_core.frames.rotations import euler123_to_dcm
from gcs_core.io.importer import load_mission
from gcs_core.noise.measured import white_noise
from gcs_tui.cli import commands as cli

DATA = TEST_DATA / "astropi"
CSV = DATA / "astropi_extract.csv"
TLE = DATA / "iss-2022-01-31.tle"
one_nT = 1.0


def _convert(tmp_path, source=CSV, tle=TLE, name="m", **kw):
    return convert("astropi", source, tmp_path / name, tle=tle, **kw)


def test_extract_converts_to_a_mission_gcs_import_accepts(tmp_path):
    rep = _convert(tmp_path)
    out = tmp_path / "m"
    assert rep.rows == 80 and rep.samples["MAG"] == 80
    # the steep settle (12.7, 26.2, 31.9, 33.8, 34.9 µT) and the tail more than 3σ off the
    # steady field extrapolated back (12 here; 16 on the whole file, whose σ is smaller)
    n_tr = rep.flagged["MAG"]
    assert 5 <= n_tr <= 16
    for f in ("mission.toml", "orbit.tle", "telemetry/MAG.csv", "aux.csv", "LICENCE.md", "SOURCE.md", "PROVENANCE.md"):
        assert (out / f).is_file(), f
    m = load_mission(out)
    assert m.spec.orbit_tle == out / "orbit.tle" and m.spec.ephemeris_file is None
    mag = m.telemetry["MAG"]
    assert len(mag) == 80 - n_tr  # flagged rows kept in the file, unused
    assert any(f"{n_tr} rows flagged" in r for r in m.report.repairs)
    flags = np.loadtxt(out / "telemetry" / "MAG.csv", delimiter=",", skiprows=3)[:, 4]
    assert flags.size == 80 and np.all(flags[:n_tr] == 1) and np.all(flags[n_tr:] == 0)
    # µT -> nT, every unflagged row
    src = np.genfromtxt(CSV, delimiter=",", skip_header=1, usecols=(7, 8, 9))
    np.testing.assert_allclose(mag.stack(("bx", "by", "bz")), src[n_tr:] * 1000.0, atol=1e-6 * one_nT)
    # the ephemeris covers the telemetry with the margin, at 10 s
    assert m.ephemeris_table.t[0] <= mag.t[0] - 100 and m.ephemeris_table.t[-1] >= mag.t[-1] + 100
    # aux channels by name, centred ones about their median
    assert set(m.aux.columns) == {"t", "dtemp_c", "dhumidity_pct", "dpressure_hpa", "light_clear"}
    text = (out / "mission.toml").read_text()
    assert "ESTIMATED from the data" in text and "ESTIMATED, not a data book" in text
    assert "CC BY-SA 4.0" in (out / "PROVENANCE.md").read_text()


def test_cli_convert_then_import(tmp_path, capsys):
    out = tmp_path / "mission"
    assert cli.main(["-q", "convert", "astropi", str(CSV), "--tle", str(TLE), "--out", str(out)]) == 0
    assert "flagged" in capsys.readouterr().out
    assert cli.main(["-q", "import", str(out)]) == 0
    # a second run refuses the non-empty directory, --force replaces it
    assert cli.main(["-q", "convert", "astropi", str(CSV), "--tle", str(TLE), "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert cli.main(["-q", "convert", "astropi", str(CSV), "--tle", str(TLE), "--out", str(out), "--force"]) == 0


def _edited(tmp_path, edit) -> Path:
    lines = CSV.read_text().splitlines()
    lines = edit(lines)
    p = tmp_path / "bad.csv"
    p.write_text("\n".join(lines) + "\n")
    return p


def _drop_column(lines, name):
    j = lines[0].split(",").index(name)
    return [",".join(f for i, f in enumerate(ln.split(",")) if i != j) for ln in lines]


def _set_field(lines, line_no, name, value):
    j = lines[0].split(",").index(name)
    fields = lines[line_no - 1].split(",")
    fields[j] = value
    lines[line_no - 1] = ",".join(fields)
    return lines


@pytest.mark.parametrize(
    "edit, where",
    [
        (lambda ls: _drop_column(ls, "MagY"), ("MagY", 1)),
        (lambda ls: _set_field(ls, 12, "MagZ", "1.2.3"), ("'MagZ'", 12)),
        (lambda ls: _set_field(ls, 9, "MagX", "nan"), ("'MagX'", 9)),
        (lambda ls: _set_field(ls, 7, "Date/Time", "31/01/2022 12:21:45"), ("Date/Time", 7)),
        (lambda ls: _set_field(ls, 8, "Date/Time", "2022-01-31 12:21:15"), ("does not follow", 8)),
        (lambda ls: ls[:5] + [ls[5] + ",extra"] + ls[6:], ("fields where the header", 6)),
    ],
    ids=["missing column", "bad number", "nan", "bad time", "time goes back", "extra field"],
)
def test_malformed_file_one_line_with_file_line_column(tmp_path, edit, where):
    bad = _edited(tmp_path, edit)
    with pytest.raises(InputError) as err:
        _convert(tmp_path, source=bad)
    msg = str(err.value)
    text, line = where
    assert "\n" not in msg and str(bad) in msg and text in msg
    assert err.value.line == line
    assert not (tmp_path / "m").exists()  # nothing half-written


def test_bad_number_names_the_character_column(tmp_path):
    bad = _edited(tmp_path, lambda ls: _set_field(ls, 12, "MagZ", "x"))
    with pytest.raises(InputError) as err:
        _convert(tmp_path, source=bad)
    line = bad.read_text().splitlines()[11]
    assert line[err.value.column - 1] == "x"


def test_bad_or_missing_tle(tmp_path):
    with pytest.raises(InputError, match="two-line elements"):
        _convert(tmp_path, tle=None)
    bad = tmp_path / "bad.tle"
    text = TLE.read_text().splitlines()
    text[1] = text[1][:-1] + str((int(text[1][-1]) + 1) % 10)  # break the checksum
    bad.write_text("\n".join(text))
    with pytest.raises(InputError) as err:
        _convert(tmp_path, tle=bad)
    assert err.value.line == 2 and err.value.column == 69


def test_registry_is_lazy_and_names_unknown_formats():
    assert CONVERTERS["astropi"] == "gcs_core.convert.astropi"
    assert CONVERTERS["broad"] == "gcs_core.convert.broad"
    assert converter("astropi").convert is not None
    with pytest.raises(InputError, match="known: astropi, broad"):
        converter("nope")


def test_white_noise_and_transient_against_known_truth():
    """Seeded: white noise σ = 150 nT on a field moving along an orbit (a slope and a
    curvature far larger than σ per sample), after a 20-sample exponential settle."""
    rng = np.random.default_rng(12)
    n, sigma = 8000, np.array([120.0, 150.0, 190.0])
    t = np.arange(n) * 5.0
    signal = 30000.0 * np.column_stack([np.sin(2 * np.pi * t / 5560 + k) for k in range(3)])
    y = signal + rng.normal(0.0, sigma, (n, 3))
    est = white_noise(t, y)
    # σ of a std estimate from n second differences (correlated, lag ≤ 2): ≈ σ √(35/18 / n)
    tol = 4.0 * sigma * math.sqrt(35.0 / 18.0 / n)
    np.testing.assert_array_less(np.abs(est - sigma), tol)
    assert leading_transient(y, est) == 0
    settle = -25000.0 * np.exp(-t / 5.0)[:, None] * np.ones(3)
    # the settle falls below σ (120 nT) after ln(25000/120) = 5.3 time constants: 6 samples;
    # below the 3σ test of the tail after 4.2
    assert 5 <= leading_transient(y + settle, est, t=t) <= 7


def test_procrustes_recovers_a_mounting():
    rng = np.random.default_rng(3)
    B_L = rng.normal(0.0, 30000.0, (500, 3))
    M_true = euler123_to_dcm(0.3, -1.1, 2.0)
    b_true = np.array([-4000.0, 1500.0, 700.0])
    B_S = B_L @ M_true.T + b_true + rng.normal(0.0, 150.0, (500, 3))
    M, b = procrustes_mounting(B_S, B_L)
    # angle σ per axis ≈ 150 nT / (42 µT √500) = 0.01°
    assert np.degrees(np.arccos((np.trace(M.T @ M_true) - 1) / 2)) < 0.05
    np.testing.assert_allclose(b, b_true, atol=30.0 * one_nT)  # 4.5σ/√500 ≈ 30 nT


def test_extract_keeps_the_original_unchanged(tmp_path):
    copy = tmp_path / "src.csv"
    shutil.copyfile(CSV, copy)
    before = copy.read_bytes()
    _convert(tmp_path, source=copy)
    assert copy.read_bytes() == before


def test_a_new_format_is_one_module_and_options_it_does_not_take_are_refused(monkeypatch):
    import sys
    import types

    mod = types.ModuleType("fake_format_converter")
    mod.convert = lambda source, out: ("converted", source, out)
    monkeypatch.setitem(sys.modules, "fake_format_converter", mod)
    monkeypatch.setitem(CONVERTERS, "fake", "fake_format_converter")
    assert convert("fake", "a.csv", "m", tle=None, overwrite=False)[0] == "converted"
    with pytest.raises(InputError) as err:
        convert("fake", "a.csv", "m", tle="x.tle")
    assert err.value.key == "tle" and "does not apply" in str(err.value)


def test_prediction_beyond_the_data_propagates_the_tle(tmp_path):
    """A plan past the telemetry (the next hour) takes its orbit from the mission's TLE."""
    from gcs_core.predictor.plan import DataPlan
    from gcs_core.predictor.predict import predict

    _convert(tmp_path)
    m = load_mission(tmp_path / "m")
    res = predict(m, plan=DataPlan(3600.0, 7200.0, step=60.0))
    assert res.times[0] >= 3600.0 and res.times[-1] <= 7200.0
    assert np.all(np.isfinite(res.sigma)) and res.frames["MAG"] > 0
