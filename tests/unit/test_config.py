"""The analysis config (gcs_core/config.py): every documented key round-trips through save
and load, every refusal names its key, the sample configs load, and docs/input_checks.md
lists every message the loader gives."""

from __future__ import annotations

import ast
import math
import re
from dataclasses import replace
from pathlib import Path

import pytest
from config_example import example_config_text
from repo_paths import ROOT

from gcs_core import config as C
from gcs_core import config_checks
from gcs_core import config_schema as S
from gcs_core.errors import ConfigError, InputError
from gcs_core.io.importer import load_mission

MISSIONS = ROOT / "sample_data" / "missions"
CONFIGS = ROOT / "sample_data" / "configs"
MISSION = MISSIONS / "hidden-tam-contamination"


def example_text(mission: Path) -> str:
    """The documented example config (gcs_core/config.py's docstring and the planning
    tables of gcs_core/trade/__init__.py's), pointed at ``mission``."""
    text = example_config_text()
    return re.sub(r'^mission = "[^"]*"', f'mission = "{mission.as_posix()}"', text, flags=re.MULTILINE)


def leaves(d, prefix=""):
    """Dotted leaf keys of a TOML document (lists of tables indexed from 1)."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v:
            out.update(leaves(v, key + "."))
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for i, x in enumerate(v, start=1):
                out.update(leaves(x, f"{key}[{i}]."))
        else:
            out[key] = v
    return out


def write(tmp_path: Path, text: str, name: str = "a.toml") -> Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


BASE = f'[analysis]\nmission = "{MISSION.as_posix()}"\n'


# ---------------------------------------------------------------------------- round trip
def test_documented_example_loads_with_every_key(tmp_path):
    path = write(tmp_path, example_text(MISSION))
    cfg = C.load_config(path)
    assert cfg.mission == MISSION and cfg.method == "whole_span" and cfg.name == "nominal, first look"
    assert cfg.physics.as_dict() == {
        "stellar_aberration": True,
        "solar_aberration": True,
        "sun_parallax": True,
        "earth_oblateness": True,
        "field_model": "igrf",
    }
    assert cfg.models == {"CSS1": "coarse_sun", "IRU": "gyro"}
    assert cfg.state.effects == ("TAM1.alignment",) and cfg.state.exclude == ()
    assert cfg.state.elements == {"TAM1.bias_x": S.ElementConfig("solve-for", 0.0, 200.0)}
    assert cfg.state.attitude_sigma_deg == 1.0
    assert cfg.filter == S.FilterConfig(600.0, 5.0, 20, {"FHST1": 4.0}, "long_run", 1.0, 2, ("FHST1",))
    assert (cfg.diagnosis.significance, cfg.diagnosis.holdout_fraction) == (0.001, 0.25)
    p = cfg.prediction
    assert (p.start, p.end, p.step, p.gaps) == (0.0, 7200.0, 10.0, ((1800.0, 2400.0),))
    assert cfg.prediction.maneuvers == (S.Maneuver(3000.0, 600.0, "yaw", 0.1),)
    assert cfg.verification.requirement_deg == 0.01


def test_every_documented_key_survives_save_and_load(tmp_path):
    src = write(tmp_path, example_text(MISSION))
    documented = leaves(C.parse_toml(src.read_text()))
    cfg = C.load_config(src)
    saved = C.save_config(cfg, tmp_path / "sub" / "saved.toml")
    written = leaves(C.parse_toml(saved.read_text()))
    assert set(documented) <= set(written), set(documented) - set(written)
    for key, value in documented.items():
        if key != "analysis.mission":  # written relative to the new file
            assert written[key] == value, key
    again = C.load_config(saved)
    assert replace(again, path=None) == replace(cfg, path=None)
    assert again.digest() == cfg.digest()


def test_documented_example_names_every_key_the_loader_knows():
    doc = C.parse_toml(example_text(MISSION))
    for table, keys in S.TABLES.items():
        assert table in doc, table
        for k in keys:
            assert k in doc[table], f"{table}.{k} is not in the docstring example"
    assert set(doc["prediction"]["maneuvers"][0]) == set(config_checks.MANEUVER_KEYS)
    assert set(doc["state"]["elements"]["TAM1.bias_x"]) == set(config_checks.ELEMENT_KEYS)


def test_infinite_sigma_and_label_round_trip(tmp_path):
    cfg = C.load_config(write(tmp_path, BASE + 'name = "run 1"\n[state.elements."CSS1.b_alpha"]\nsigma = inf\n'))
    assert cfg.state.elements["CSS1.b_alpha"].sigma == math.inf
    again = C.load_config(C.save_config(cfg, tmp_path / "b.toml"))
    assert again.state.elements == cfg.state.elements and again.name == "run 1"
    assert replace(cfg, name=None).digest() == cfg.digest()  # the label is not a setting


def test_relative_mission_resolves_against_the_config_folder(tmp_path):
    (tmp_path / "cfg").mkdir()
    cfg = C.load_config(write(tmp_path / "cfg", '[analysis]\nmission = "../missions/m1"\n'))
    assert cfg.mission == tmp_path / "missions" / "m1"


# ---------------------------------------------------------------------------- refusals
REFUSALS = [
    # (TOML after the [analysis] table, key named, part of the message)
    ('method = "fast"\n', "analysis.method", "must be one of whole_span, batch, kalman"),
    ("name = 3\n", "analysis.name", "must be a string"),
    ('colour = "red"\n', "analysis.colour", "unknown key"),
    ("[physcs]\n", "physcs", "did you mean 'physics'"),
    ('[physics]\nsun_parallax = "yes"\n', "physics.sun_parallax", "must be true or false"),
    ('[physics]\nfield_model = "wmm"\n', "physics.field_model", "must be one of igrf, dipole"),
    ("[physics]\nrelativity = true\n", "physics.relativity", "unknown key"),
    ('[models]\nTAM1 = "magnetic"\n', "models.TAM1", "must be the sensor's type"),
    ("[models]\nTAM1 = 1\n", "models.TAM1", "must be the sensor's type"),
    ('[state]\neffects = "TAM1.scale"\n', "state.effects", "must be a list"),
    ('[state]\neffects = ["TAM1.scale", "scale"]\n', "state.effects[2]", "must be an effect id"),
    ("[state]\nexclude = [3]\n", "state.exclude[1]", "must be an effect id"),
    ("[state]\nattitude_sigma_deg = 0\n", "state.attitude_sigma_deg", "must be > 0"),
    ('[state]\nattitude_sigma_deg = "1"\n', "state.attitude_sigma_deg", "must be a number"),
    ("[state]\nelements = 3\n", "state.elements", "must be a table"),
    (
        '[state.elements."TAM1.bias_x"]\nrole = "fixed"\n',
        'state.elements."TAM1.bias_x".role',
        "must be one of solve-for, consider, held",
    ),
    ('[state.elements."TAM1.bias_x"]\nsigma = -2.0\n', 'state.elements."TAM1.bias_x".sigma', "must be > 0"),
    ('[state.elements."TAM1.bias_x"]\nvalue = nan\n', 'state.elements."TAM1.bias_x".value', "not nan"),
    ('[state.elements."TAM1.bias_x"]\nvalue = inf\n', 'state.elements."TAM1.bias_x".value', "must be finite"),
    ('[state.elements."TAM1.bias_x"]\nsigam = 2.0\n', 'state.elements."TAM1.bias_x".sigam', "did you mean 'sigma'"),
    ("[state.elements]\nbias = {sigma = 1.0}\n", "state.elements.bias", "must be an element name"),
    ("[filter]\nblock_seconds = true\n", "filter.block_seconds", "must be a number, not True"),
    ("[filter]\nedit_k = -1\n", "filter.edit_k", "must be ≥ 0.0"),
    ("[filter.edit_k_sensor]\nFHST1 = -3\n", "filter.edit_k_sensor.FHST1", "must be ≥ 0.0"),
    ('[filter.edit_k_sensor]\nFHST1 = "tight"\n', "filter.edit_k_sensor.FHST1", "must be a number"),
    ("[filter]\nedit_k_sensor = 4\n", "filter.edit_k_sensor", "must be a table"),
    ("[filter]\nmax_iterations = 2.5\n", "filter.max_iterations", "must be a whole number"),
    ("[filter]\nmax_iterations = 0\n", "filter.max_iterations", "must be ≥ 1"),
    ('[filter]\nnoise_weighting = "white"\n', "filter.noise_weighting", "must be one of correlated, stated, long_run"),
    ("[filter]\nnoise_window = 0\n", "filter.noise_window", "must be > 0"),
    ("[filter]\nnoise_passes = 4\n", "filter.noise_passes", "must be ≤ 3"),
    ('[filter]\nnoise_sensors = "OPT"\n', "filter.noise_sensors", "must be a list"),
    ("[filter]\nnoise_sensors = [3]\n", "filter.noise_sensors[1]", "must be a sensor name"),
    ("[diagnosis]\nsignificance = 0.9\n", "diagnosis.significance", "must be ≤ 0.5"),
    ('[diagnosis]\nholdout_fraction = "quarter"\n', "diagnosis.holdout_fraction", "must be a number"),
    ("[prediction]\nstep = 0\n", "prediction.step", "must be > 0"),
    ("[prediction]\nstart = 100.0\nend = 50.0\n", "prediction.end", "must be later than prediction.start"),
    ("[prediction]\ngaps = [[1.0, 2.0], [5.0, 3.0]]\n", "prediction.gaps[2]", "start < end"),
    ('[prediction]\ngaps = [["a", "b"]]\n', "prediction.gaps[1]", "pair of numbers"),
    ("[prediction]\nmaneuvers = [1]\n", "prediction.maneuvers[1]", "must be a table"),
    (
        '[[prediction.maneuvers]]\nstart = 0.0\nduration = 60.0\naxis = "up"\nrate_deg_s = 0.1\n',
        "prediction.maneuvers[1].axis",
        "must be one of roll, pitch, yaw",
    ),
    (
        '[[prediction.maneuvers]]\nstart = 0.0\naxis = "yaw"\nrate_deg_s = 0.1\n',
        "prediction.maneuvers[1].duration",
        "missing",
    ),
    ("[verification]\nrequirement_deg = -0.01\n", "verification.requirement_deg", "must be > 0"),
    ("[verification]\nrequirement = 0.01\n", "verification.requirement", "did you mean 'requirement_deg'"),
]


@pytest.mark.parametrize("body, key, fragment", REFUSALS, ids=[r[1] for r in REFUSALS])
def test_each_refusal_names_its_key(tmp_path, body, key, fragment):
    path = write(tmp_path, BASE + body)
    with pytest.raises(ConfigError) as info:
        C.load_config(path)
    err = info.value
    assert err.key == key
    assert fragment in err.message
    text = str(err)
    assert text.startswith(f"{path}, key '{key}': ") and "\n" not in text


def test_mission_key_is_required_and_a_string(tmp_path):
    for text, fragment in (
        ("[analysis]\n", "missing"),
        ("[analysis]\nmission = 3\n", "as a string"),
        ('[analysis]\nmission = ""\n', "as a string"),
        ("[physics]\n", "missing"),
    ):
        with pytest.raises(ConfigError) as info:
            C.load_config(write(tmp_path, text))
        assert info.value.key == "analysis.mission" and fragment in info.value.message


def test_toml_syntax_error_names_line_and_column(tmp_path):
    path = write(tmp_path, BASE + "[filter\nedit_k = 2\n")
    with pytest.raises(ConfigError) as info:
        C.load_config(path)
    assert (info.value.line, info.value.column) == (3, 8)
    assert str(info.value).startswith(f"{path}:3:8: TOML syntax error")


def test_bad_bytes_and_missing_files_name_the_place(tmp_path):
    path = tmp_path / "bin.toml"
    path.write_bytes(BASE.encode() + b'name = "caf\xe9"\n')
    with pytest.raises(ConfigError) as info:
        C.load_config(path)
    assert (info.value.line, info.value.column) == (3, 12) and "byte 0xe9" in info.value.message
    with pytest.raises(ConfigError, match="config file not found"):
        C.load_config(tmp_path / "absent.toml")
    with pytest.raises(ConfigError, match="is a directory"):
        C.load_config(tmp_path)


def test_checks_against_the_mission_name_the_key(tmp_path):
    spec = load_mission(MISSION).spec
    cases = [
        ('[models]\nTAM9 = "magnetometer"\n', "models.TAM9", "no sensor named 'TAM9'"),
        ('[models]\nTAM1 = "gyro"\n', "models.TAM1", "sensor TAM1 is a magnetometer"),
        ('[state]\neffects = ["XYZ.scale"]\n', "state.effects[1]", "no sensor named 'XYZ'"),
        ('[state.elements."FOO.bias"]\nsigma = 1.0\n', 'state.elements."FOO.bias"', "no sensor named 'FOO'"),
    ]
    for body, key, fragment in cases:
        cfg = C.load_config(write(tmp_path, BASE + body))
        with pytest.raises(ConfigError) as info:
            config_checks.check_against_mission(cfg, spec)
        assert info.value.key == key and fragment in info.value.message
        assert info.value.file == cfg.path
    config_checks.check_against_mission(C.load_config(write(tmp_path, BASE + '[models]\nTAM1 = "off"\n')), spec)


# ---------------------------------------------------------------------------- sample configs
SAMPLES = sorted(CONFIGS.glob("*.toml"))


def test_there_is_a_sample_config_per_sample_mission():
    assert {p.stem for p in SAMPLES} == {d.name for d in MISSIONS.iterdir() if (d / "mission.toml").is_file()}


@pytest.mark.parametrize("path", SAMPLES, ids=[p.stem for p in SAMPLES])
def test_sample_config_loads_and_points_at_its_mission(path):
    cfg = C.load_config(path)
    assert cfg.mission.is_dir() and (cfg.mission / "mission.toml").is_file()
    assert cfg.mission.resolve() == (MISSIONS / path.stem).resolve()
    spec = load_mission(cfg.mission).spec
    config_checks.check_against_mission(cfg, spec)
    assert spec.name == path.stem
    shown = set(leaves(C.parse_toml(path.read_text())))
    for table in S.TABLES:  # each sample shows every table of the example
        assert any(k == table or k.startswith(table + ".") for k in shown), (path.name, table)


# ---------------------------------------------------------------------------- docs in sync
_MESSAGE_ARG = {"_require": 2, "_fail": 1, "ConfigError": 0, "InputError": 0}


def _template(node) -> str | None:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        text = node.value
    elif isinstance(node, ast.JoinedStr):
        text = "".join(v.value if isinstance(v, ast.Constant) else "…" for v in node.values)
    else:
        return None
    return re.sub(r"\{[^{}]*\}", "…", text)


def test_config_checks_doc_in_sync():
    """docs/input_checks.md tables the messages of gcs_core/config.py (and its checks, with the
    complaints of gcs_core/toml_values.py) and gcs_tui/cli/commands.py."""
    raised = set()
    for node in ast.walk(ast.parse((ROOT / "gcs_core" / "toml_values.py").read_text(encoding="utf-8"))):
        if isinstance(node, ast.Return) and (t := _template(node.value)) and t.startswith("must"):
            raised.add(t)
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "error" and node.args:
            raised.add(_template(node.args[0]))
    for source in (
        ROOT / "gcs_core" / "config.py",
        ROOT / "gcs_core" / "config_checks.py",
        ROOT / "gcs_tui" / "cli" / "commands.py",
    ):
        for node in ast.walk(ast.parse(source.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call):
                name = node.func.id if isinstance(node.func, ast.Name) else getattr(node.func, "attr", None)
                k = _MESSAGE_ARG.get(name)
                if k is not None and len(node.args) > k:
                    t = _template(node.args[k])
                    if t:
                        raised.add(t)
    doc = (ROOT / "docs" / "input_checks.md").read_text(encoding="utf-8")
    section = doc[doc.index("## The analysis config (TOML)") :]
    documented = set(re.findall(r"^\|[^|\n]*\| `([^`]+)` \|\s*$", section, re.MULTILINE))
    assert raised - documented == set(), f"add to docs/input_checks.md: {sorted(raised - documented)}"
    assert documented - raised == set(), f"stale in docs/input_checks.md: {sorted(documented - raised)}"


def test_config_errors_are_input_errors():
    assert issubclass(ConfigError, InputError)


# ---------------------------------------------------------------------------- the nested tables
def test_tables_and_the_fit_key_come_from_the_dataclasses():
    """``TABLES`` lists each table dataclass's fields; the fit key ignores exactly the tables
    marked as not changing a fit (the plan, the requirement, the planning tables)."""
    from dataclasses import fields

    assert S.TABLES["filter"] == tuple(f.name for f in fields(S.FilterConfig))
    assert S.TABLES["prediction"] == tuple(f.name for f in fields(S.PredictionConfig))
    base = S.AnalysisConfig(mission=MISSION)
    same = base.with_changes(
        prediction={"start": 10.0, "end": 99.0, "step": 3.0},
        verification={"requirement_deg": 0.5},
        trade={"top": 2},
        path=Path("x.toml"),
    )
    assert C.fit_key(same) == C.fit_key(base)
    for changed in (
        base.with_changes(filter={"edit_k": 4.0}),
        base.with_changes(diagnosis={"significance": 0.01}),
        base.with_changes(physics={"sun_parallax": False}),
        base.with_changes(method="batch"),
        base.with_changes(state={"effects": ("TAM1.alignment",)}),
    ):
        assert C.fit_key(changed) != C.fit_key(base)


def test_config_for_opens_what_either_face_is_given(tmp_path):
    """One rule for ``gcs <command> TARGET`` and the TUI's open: a mission directory or its
    mission.toml gives the default config, a .toml file is read, anything else is refused."""
    assert C.config_for(MISSION) == C.default_config(MISSION)
    assert C.config_for(MISSION / "mission.toml") == C.default_config(MISSION)
    path = write(tmp_path, BASE + "[diagnosis]\nsignificance = 0.01\n")
    assert C.config_for(path).diagnosis.significance == 0.01
    with pytest.raises(ConfigError, match="no such mission directory or config file"):
        C.config_for(tmp_path / "nothing-here")


def test_noise_weighting_round_trips_and_the_default_is_not_written(tmp_path):
    """``[filter] noise_weighting`` (gcs_core/noise/weighting.py): "long_run" and its
    keys survive save and load; at the defaults nothing is written, so a config's digest
    is the one it had before the keys existed."""
    cfg = C.load_config(write(tmp_path, BASE))
    assert cfg.filter.noise_weighting == "correlated"  # the default (issue 27)
    saved = C.save_config(cfg, tmp_path / "plain.toml").read_text()
    assert "noise_" not in saved
    on = cfg.with_changes(filter={"noise_weighting": "long_run", "noise_window": 2.0, "noise_sensors": ("TAM1",)})
    again = C.load_config(C.save_config(on, tmp_path / "on.toml"))
    assert again.filter == on.filter and again.digest() == on.digest() != cfg.digest()
    spec = load_mission(MISSION).spec
    config_checks.check_against_mission(again, spec)
    with pytest.raises(ConfigError, match="no sensor named 'OPT'") as err:
        config_checks.check_against_mission(on.with_changes(filter={"noise_sensors": ("OPT",)}), spec)
    assert err.value.key == "filter.noise_sensors[1]"
