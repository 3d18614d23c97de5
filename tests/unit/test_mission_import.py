"""Importing mission directories: the example must load; broken copies are refused in one
line that names the place (ICD §1-§6, docs/input_checks.md)."""

from __future__ import annotations

import logging
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from repo_paths import ROOT

from gcs_core.ephem.timescale import parse_utc
from gcs_core.errors import InputError
from gcs_core.io.importer import load_mission
from gcs_core.io.mission import read_mission_spec


@pytest.fixture
def mission(example_dir, tmp_path) -> Path:
    """A writable copy of the example mission."""
    dst = tmp_path / "mission"
    shutil.copytree(example_dir, dst, copy_function=shutil.copyfile)
    for root, _dirs, files in os.walk(dst):
        os.chmod(root, 0o755)
        for f in files:
            os.chmod(os.path.join(root, f), 0o644)
    return dst


def edit_lines(path: Path, fn) -> None:
    lines = path.read_text().split("\n")
    fn(lines)
    path.write_text("\n".join(lines))


def edit_toml(mission: Path, old: str, new: str, count: int = 1) -> None:
    toml = mission / "mission.toml"
    text = toml.read_text()
    assert old in text, old
    toml.write_text(text.replace(old, new, count))


def line_of(path: Path, needle: str, start: int = 1) -> int:
    for i, line in enumerate(path.read_text().split("\n"), start=1):
        if i >= start and needle in line:
            return i
    raise AssertionError(needle)


def refused(mission: Path) -> str:
    with pytest.raises(InputError) as info:
        load_mission(mission)
    message = str(info.value)
    assert "\n" not in message, message
    return message


# --- the example loads ----------------------------------------------------------------


def test_example_mission_loads(example_dir):
    m = load_mission(example_dir)
    assert m.spec.name == "sunpoint-nominal"
    assert m.spec.epoch == parse_utc("2024-03-20T06:00:00Z")
    assert [s.name for s in m.spec.sensors] == ["TAM1", "IRU", "FHST1", "FHST2", "FSS1", "CSS1"]
    assert len(m.telemetry["TAM1"]) == 7201
    assert m.report.file("telemetry TAM1").rows == 7201
    assert m.ephemeris_table.stack(("rx", "ry", "rz")).shape[1] == 3
    assert m.aux is not None and "tam_temp" in m.aux.columns
    assert m.onboard is not None and len(m.onboard) == 721
    assert m.report.dropped_nan == 0 and m.report.dropped_duplicates == 0
    assert m.report.unknown_keys == () and m.report.repairs == ()
    assert m.spec.sensor("IRU").noise is None and m.spec.sensor("IRU").get("electronic") == 0.0


# --- CSV rules, through the importer ----------------------------------------------------


def test_missing_column(mission):
    path = mission / "telemetry/TAM1.csv"
    edit_lines(path, lambda ls: ls.__setitem__(slice(None), [",".join(l.split(",")[:3]) for l in ls]))
    message = refused(mission)
    assert f"{path}:1" in message and "column 'bz'" in message


def test_unsorted_times(mission):
    path = mission / "telemetry/TAM1.csv"

    def swap(ls):
        ls[10], ls[11] = ls[11], ls[10]

    edit_lines(path, swap)
    message = refused(mission)
    assert f"{path}:12:1:" in message and "sorted" in message


def test_text_in_a_number(mission):
    path = mission / "telemetry/FSS1.csv"
    edit_lines(path, lambda ls: ls.__setitem__(20, ls[20].split(",")[0] + ",1,two"))
    message = refused(mission)
    assert f"{path}:21:3:" in message and "'two'" in message and "'n_beta'" in message


def test_nan_rows_dropped_and_counted(mission):
    path = mission / "telemetry/TAM1.csv"

    def blank(ls):
        ls[5] = ls[5].rsplit(",", 1)[0] + ","
        ls[6] = ls[6].split(",")[0] + ",nan,1,2"
        ls[7] = ls[7].split(",")[0] + ",,,"

    edit_lines(path, blank)
    m = load_mission(mission)
    assert len(m.telemetry["TAM1"]) == 7201 - 3
    assert m.telemetry["TAM1"].dropped_nan == 3
    assert m.report.file("telemetry TAM1").dropped_nan == 3
    assert any("TAM1.csv" in r and "3 rows" in r for r in m.report.repairs)


def test_duplicate_packets_dropped_and_counted(mission):
    path = mission / "telemetry/IRU.csv"
    edit_lines(path, lambda ls: (ls.insert(100, ls[100]), ls.insert(200, ls[200])))
    m = load_mission(mission)
    assert len(m.telemetry["IRU"]) == 7200
    assert m.report.file("telemetry IRU").dropped_duplicates == 2
    assert m.report.dropped_duplicates == 2


def test_same_time_different_rows(mission):
    path = mission / "telemetry/IRU.csv"

    def dup(ls):
        t, *rest = ls[100].split(",")
        ls.insert(101, ",".join([t, "0.0", "0.0", "0.0"]))

    edit_lines(path, dup)
    message = refused(mission)
    assert f"{path}:102:2:" in message and "same time" in message and "lines 101 and 102" in message


# --- mission.toml ---------------------------------------------------------------------------


def test_unknown_sensor_type(mission):
    edit_toml(mission, 'type = "coarse_sun"', 'type = "sextant"')
    toml = mission / "mission.toml"
    message = refused(mission)
    assert f"{toml}:{line_of(toml, 'sextant')}" in message
    assert "key 'sensor[6].type'" in message and "'sextant'" in message


def test_missing_telemetry_file(mission):
    (mission / "telemetry/CSS1.csv").unlink()
    toml = mission / "mission.toml"
    message = refused(mission)
    assert f"{toml}:{line_of(toml, 'telemetry/CSS1.csv')}" in message
    assert "not found" in message and "sensor[6].telemetry" in message


def test_bad_toml(mission):
    edit_toml(mission, "noise = 25.0", "noise = = 25.0")
    toml = mission / "mission.toml"
    message = refused(mission)
    assert f"{toml}:{line_of(toml, 'noise = = 25.0')}:" in message
    assert "TOML syntax error" in message


def test_duplicate_sensor_names(mission):
    edit_toml(mission, 'name = "FHST2"', 'name = "FHST1"')
    toml = mission / "mission.toml"
    message = refused(mission)
    second = line_of(toml, 'name = "FHST1"', line_of(toml, 'name = "FHST1"') + 1)
    assert f"{toml}:{second}" in message and "used twice" in message


@pytest.mark.parametrize(
    "old,new,key,needle",
    [
        ("noise = 25.0", "noise = -25.0", "sensor[1].noise", "must be > 0"),
        ("fov_deg = 32.0", "fov_deg = 95.0", "sensor[5].fov_deg", "(0, 90]"),
        ('attitude_mode = "sun_pointing"', 'attitude_mode = "tumbling"', "mission.attitude_mode", "one of"),
        ('epoch = "2024-03-20T06:00:00Z"', 'epoch = "2024-13-20T06:00:00Z"', "mission.epoch", "valid date"),
        ("scale = [1.0, 1.0]", "scale = [1.0]", "sensor[3].scale", "list of 2"),
        ("arw = 3.162278e-07", 'arw = "small"', "sensor[2].arw", "must be a number"),
        ("alignment_deg = [0.0, 0.0, 0.0]\nnoise = 25.0", "noise = 25.0", "sensor[1].alignment_deg", "missing key"),
        ('type = "coarse_sun"', 'type = "horizon"', "sensor[6].type", "spinning"),
    ],
)
def test_bad_data_book_values(mission, old, new, key, needle):
    edit_toml(mission, old, new)
    message = refused(mission)
    assert f"key '{key}'" in message and needle in message
    assert "mission.toml:" in message


def test_unknown_keys_kept_and_reported(mission, caplog):
    edit_toml(mission, "noise = 25.0", "noise = 25.0\ngain = 1.02")
    edit_toml(mission, 'attitude_mode = "sun_pointing"', 'attitude_mode = "sun_pointing"\nowner = "x"')
    with caplog.at_level(logging.WARNING):
        m = load_mission(mission)
    tam = m.spec.sensor("TAM1")
    assert tam.unknown_keys == ("gain",) and tam.get("gain") == 1.02
    assert "mission.owner" in m.spec.unknown_keys
    assert set(m.report.unknown_keys) == {"mission.owner", "sensor[TAM1].gain"}
    assert "gain" in caplog.text and "owner" in caplog.text


def test_mission_spec_accepts_the_toml_path_and_spinning_keys(mission):
    spec = read_mission_spec(mission / "mission.toml")
    assert spec.root == mission and spec.attitude_mode == "sun_pointing"


# --- ephemeris and physical ranges -------------------------------------------------------


def test_ephemeris_not_covering_telemetry(mission):
    eph = mission / "ephemeris.csv"
    edit_lines(eph, lambda ls: ls.__delitem__(slice(122, None)))  # keep t <= 3600 s
    message = refused(mission)
    tam = mission / "telemetry/TAM1.csv"
    assert f"{tam}:" in message and str(eph) in message
    assert "3600 to 7200 s is not covered" in message


def test_ephemeris_cadence_over_60_s(mission):
    eph = mission / "ephemeris.csv"
    edit_lines(eph, lambda ls: ls.__delitem__(slice(10, 13)))
    message = refused(mission)
    assert f"{eph}:11:1:" in message and "60 s or finer" in message


def test_ephemeris_position_in_metres(mission):
    eph = mission / "ephemeris.csv"

    def metres(ls):
        f = ls[5].split(",")
        f[1:4] = [str(float(x) * 1000) for x in f[1:4]]
        ls[5] = ",".join(f)

    edit_lines(eph, metres)
    message = refused(mission)
    assert f"{eph}:6:" in message and "|r|" in message


def test_quaternion_norm_zero(mission):
    path = mission / "onboard_attitude.csv"
    edit_lines(path, lambda ls: ls.__setitem__(30, ls[30].split(",")[0] + ",0,0,0,0"))
    message = refused(mission)
    assert f"{path}:31:" in message and "quaternion norm 0" in message


def test_field_of_1e9_nT(mission):
    path = mission / "telemetry/TAM1.csv"
    edit_lines(path, lambda ls: ls.__setitem__(40, ls[40].split(",")[0] + ",1e9,0,0"))
    message = refused(mission)
    assert f"{path}:41:2:" in message and "nT" in message and "'bx'" in message


def test_gyro_rate_in_degrees(mission):
    path = mission / "telemetry/IRU.csv"
    edit_lines(path, lambda ls: ls.__setitem__(7, ls[7].split(",")[0] + ",0,0,5.0"))
    message = refused(mission)
    assert f"{path}:8:4:" in message and "rad/s" in message


def test_star_declination_out_of_range(mission):
    path = mission / "telemetry/FHST1.csv"

    def bad(ls):
        f = ls[3].split(",")
        f[4] = "95.0"
        ls[3] = ",".join(f)

    edit_lines(path, bad)
    message = refused(mission)
    assert f"{path}:4:5:" in message and "declination" in message


def test_far_future_times(mission):
    path = mission / "telemetry/CSS1.csv"
    edit_lines(path, lambda ls: ls.insert(len(ls) - 1, "400000000,0,0"))
    message = refused(mission)
    n = len(path.read_text().split("\n")) - 1
    assert f"{path}:{n}:1:" in message and "far future" in message


def test_inf_in_ephemeris_refused(mission):
    eph = mission / "ephemeris.csv"
    edit_lines(eph, lambda ls: ls.__setitem__(3, ls[3].replace(ls[3].split(",")[8], "inf", 1)))
    message = refused(mission)
    assert f"{eph}:4:9:" in message and "infinite" in message


def test_empty_telemetry_leaves_the_sensor_out(mission):
    """A sensor that never saw its target is left out and reported, not a refusal."""
    (mission / "telemetry/FHST2.csv").write_text("t,h,v,ra,dec,mag\n")
    m = load_mission(mission)
    assert "FHST2" not in m.telemetry and "FHST2" not in [s.name for s in m.spec.sensors]
    assert any("FHST2" in r and "left out" in r for r in m.report.repairs)


def test_empty_gyro_telemetry_refused(mission):
    (mission / "telemetry/IRU.csv").write_text("t,wx,wy,wz\n")
    message = refused(mission)
    assert "IRU.csv" in message and "0 data rows" in message


def test_parse_utc_forms():
    assert parse_utc("2024-03-20T06:00:00Z") == parse_utc("2024-03-20T07:00:00+01:00")
    assert parse_utc("2024-03-20 06:00:00.5").microsecond == 500000
    assert parse_utc("2024-03-20").hour == 0
    for bad in ("2024-03-20T06:00:60Z", "20 March 2024", "2024-02-30"):
        with pytest.raises(ValueError):
            parse_utc(bad)
    assert np.isclose((parse_utc("2024-01-01T00:00:00Z") - parse_utc("2023-12-31T23:59:59Z")).total_seconds(), 1.0)


# --- docs/input_checks.md lists every message the readers raise ----------------------------

#: callables whose argument at this position is a user-facing message template
_MESSAGE_ARG = {
    "InputError": 0,
    "DataFileError": 0,
    "error": 0,
    "_refuse": 3,
    "_field_error": 4,
    "_check_vector_norm": 4,
}


def _template(node) -> str | None:
    import ast
    import re

    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        text = node.value
    elif isinstance(node, ast.JoinedStr):
        text = "".join(v.value if isinstance(v, ast.Constant) else "…" for v in node.values)
    else:
        return None
    return re.sub(r"\{[^{}]*\}", "…", text)  # str.format fields, e.g. {norm:.6g}


def _code_templates() -> tuple[set[str], set[str]]:
    """(messages raised by the io readers and the noise estimate from data, every string
    template in their sources and in what they call for words: the epoch parser
    :func:`gcs_core.ephem.timescale.parse_utc` and the value complaints of :mod:`gcs_core.toml_values`)."""
    import ast

    raised, everything = set(), set()
    sources = sorted((ROOT / "gcs_core" / "io").glob("*.py")) + [
        ROOT / "gcs_core" / "noise" / "measured.py",
        ROOT / "gcs_core" / "inputs.py",
    ]
    for source in sources + [ROOT / "gcs_core" / "ephem" / "timescale.py", ROOT / "gcs_core" / "toml_values.py"]:
        for node in ast.walk(ast.parse(source.read_text())):
            t = _template(node)
            if t:
                everything.add(t)
            if isinstance(node, ast.Call):
                func = node.func
                name = func.id if isinstance(func, ast.Name) else getattr(func, "attr", None)
                k = _MESSAGE_ARG.get(name)
                if k is not None and len(node.args) > k and source in sources:
                    t = _template(node.args[k])
                    if t and t.strip("… "):
                        raised.add(t)
    return raised, everything


def test_input_checks_doc_in_sync():
    import re

    doc = (ROOT / "docs" / "input_checks.md").read_text()
    documented = {m.group(1) for m in re.finditer(r"→ `([^`]+)`\s*$", doc, re.MULTILINE)}
    raised, everything = _code_templates()
    undocumented = raised - documented
    assert not undocumented, f"add to docs/input_checks.md: {sorted(undocumented)}"
    stale = {d for d in documented if d not in everything}
    assert not stale, f"docs/input_checks.md lists messages the code no longer has: {sorted(stale)}"
