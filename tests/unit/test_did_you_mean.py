""" "Did you mean" wherever a name is typed: mission.toml keys and tables, mission and
config paths, config keys (issue 22 item 7; :mod:`gcs_core.suggest`)."""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import pytest
from repo_paths import ROOT

from gcs_core.config import config_for, load_config
from gcs_core.errors import ConfigError, InputError
from gcs_core.io.mission import read_mission_spec
from gcs_core.suggest import close_path, did_you_mean

SAMPLE = ROOT / "sample_data" / "missions" / "nominal-sunpoint"


@pytest.fixture
def mission(tmp_path) -> Path:
    """A writable copy of the bundled nominal mission's mission.toml (its data files linked)."""
    dst = tmp_path / "nominal-sunpoint"
    dst.mkdir()
    for entry in SAMPLE.iterdir():
        if entry.name != "mission.toml":
            (dst / entry.name).symlink_to(entry)
    shutil.copyfile(SAMPLE / "mission.toml", dst / "mission.toml")
    return dst


def edit(mission: Path, old: str, new: str) -> None:
    toml = mission / "mission.toml"
    text = toml.read_text()
    assert old in text, old
    toml.write_text(text.replace(old, new, 1))


def test_the_wording():
    assert did_you_mean("noize", ["noise", "bias"]) == "; did you mean 'noise'?"
    assert did_you_mean("gain", ["noise", "bias"]) == ""


def test_required_key_misspelt_names_the_typo(mission):
    edit(mission, "noise = 25.0", "noize = 25.0")
    with pytest.raises(InputError) as info:
        read_mission_spec(mission)
    message = str(info.value)
    assert "missing key 'noise'" in message and "'noize'" in message and "did you mean 'noise'?" in message
    assert "\n" not in message


def test_optional_key_misspelt_gets_the_suggestion(mission, caplog):
    edit(mission, "arw = 3.162278e-07", "arw = 3.162278e-07\nelectronc = 0.0")
    with caplog.at_level(logging.WARNING):
        spec = read_mission_spec(mission)
    assert spec.sensor("IRU").unknown_keys == ("electronc",)
    assert "'sensor[2].electronc'" in caplog.text and "did you mean 'electronic'?" in caplog.text


def test_table_misspelt_gets_the_suggestion(mission, caplog):
    edit(mission, "[onboard_attitude]", "[onboard_atitude]")
    with caplog.at_level(logging.WARNING):
        spec = read_mission_spec(mission)
    assert spec.onboard_file is None and "onboard_atitude" in spec.unknown_keys
    assert "did you mean 'onboard_attitude'?" in caplog.text


def test_mission_key_misspelt_gets_the_suggestion(mission, caplog):
    edit(mission, 'epoch = "2024', 'spin_axis_gues_deg = [0.0, 90.0]\nepoch = "2024')
    with caplog.at_level(logging.WARNING):
        read_mission_spec(mission)
    assert "did you mean 'spin_axis_guess_deg'?" in caplog.text


def test_unrelated_key_gets_no_suggestion(mission, caplog):
    edit(mission, "noise = 25.0", "noise = 25.0\nowner = 'x'")
    with caplog.at_level(logging.WARNING):
        read_mission_spec(mission)
    assert "owner" in caplog.text and "did you mean" not in caplog.text


def test_mission_path_misspelt(mission):
    typo = mission.parent / "nominal-sunpont"
    assert close_path(typo, want_dir=True) == mission
    with pytest.raises(InputError, match=r"mission directory not found; did you mean '.*nominal-sunpoint'\?"):
        read_mission_spec(typo)
    with pytest.raises(ConfigError, match=r"no such mission directory or config file; did you mean"):
        config_for(typo)


def test_config_path_misspelt(tmp_path):
    (tmp_path / "nominal.toml").write_text('[analysis]\nmission = "m"\n')
    with pytest.raises(ConfigError, match=r"config file not found; did you mean '.*nominal\.toml'\?"):
        load_config(tmp_path / "nominl.toml")


def test_nothing_close_no_suggestion(tmp_path):
    (tmp_path / "alpha").mkdir()
    with pytest.raises(InputError) as info:
        read_mission_spec(tmp_path / "zzz")
    assert "did you mean" not in str(info.value)
    assert close_path(tmp_path / "no" / "such" / "dir") is None


def test_config_key_misspelt_still_suggests(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[analysis]\nmission = "m"\n[filter]\nedit_kk = 4.0\n')
    with pytest.raises(ConfigError, match=r"filter\.edit_kk.*did you mean 'edit_k'\?"):
        load_config(cfg)
