"""The analyst's whole session, driven by keypresses alone (Pilot).

Open a mission with a hidden effect, fit, see the residuals of the affected sensor
fail (normalized RMS > 1.05), open Diagnosis, add the top candidate, refit: the top
candidate must be the hidden effect and every sensor must come down to the noise
floor (normalized RMS ≤ 1.05).

The mission is the bundled ``hidden-tam-contamination`` (answer in
``sample_data/answers``); without the sample data, the shared conformance mission is
analysed with stellar aberration switched off, which makes ``model.stellar_aberration``
the hidden effect.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from textual.widgets import DataTable
from tui_testing import sample_answer, sample_mission, settle, type_text

from gcs_core.config import save_config
from gcs_core.config_schema import AnalysisConfig
from gcs_tui.tui.app import GcsApp
from gcs_tui.tui.screens.diagnosis import DiagnosisScreen
from gcs_tui.tui.screens.residuals import ResidualsScreen

#: normalized RMS above this fails: 5 % above the noise floor
RMS_LIMIT = 1.05


def hidden_effect_case(shared_example, tmp_path: Path) -> tuple[Path, str, list[str]]:
    """(analysis config, hidden effect id, sensors it shows in) of a mission with a hidden effect."""
    name = "hidden-tam-contamination"
    mission = sample_mission(name)
    cfg = AnalysisConfig()
    if mission is not None:
        answer = sample_answer(name)
        hidden = answer["hidden_effects"][0]
        cfg = cfg.with_changes(mission=mission, physics=answer.get("physics", {}))
        sensors = [hidden["sensor"]]
        effect = hidden["id"]
    else:
        copy = tmp_path / "sunpoint-nominal"
        shutil.copytree(shared_example("sunpoint-nominal"), copy)
        cfg = cfg.with_changes(mission=copy, physics={"stellar_aberration": False})
        sensors = ["FHST1", "FHST2"]
        effect = "model.stellar_aberration"
    path = save_config(cfg, tmp_path / "analysis.toml")
    return path, effect, sensors


async def open_by_keys(pilot, path: Path) -> None:
    """``o``, clear the field, type the path, enter — and wait for the import."""
    await pilot.press("o")
    await pilot.press("ctrl+u")
    await type_text(pilot, str(path))
    await pilot.press("enter")
    await settle(pilot)


@pytest.mark.slow
async def test_find_hidden_effect_by_keys(shared_example, tmp_path):
    config, hidden, affected = hidden_effect_case(shared_example, tmp_path)
    app = GcsApp()
    async with app.run_test(size=(120, 36)) as pilot:
        await open_by_keys(pilot, config)
        wb = app.workbench
        assert wb.ready and wb.result is None

        await pilot.press("f")  # fit
        await settle(pilot)
        await pilot.press("6")  # residuals
        await settle(pilot)
        assert isinstance(app.screen, ResidualsScreen)
        before = wb.analysis.rms()
        assert max(before[s] for s in affected) > RMS_LIMIT, before

        await pilot.press("7")  # diagnosis
        await settle(pilot)
        assert isinstance(app.screen, DiagnosisScreen)
        table = app.screen.query_one("#candidates", DataTable)
        top = table.coordinate_to_cell_key((table.cursor_row, 0)).row_key.value
        assert top == hidden

        await pilot.press("a")  # add the selected (top) candidate, refit
        await settle(pilot)
        await pilot.press("f")  # refit from the config
        await settle(pilot)
        after = wb.analysis.rms()
        assert hidden in wb.analysis.effects_in_state()
        assert all(v <= RMS_LIMIT for v in after.values()), after
        assert [s.action for s in wb.analysis.steps] == ["fit", "add"]

        await pilot.press("q")
    assert app.return_code in (0, None)


@pytest.mark.slow
async def test_editing_screens_by_keys(shared_example, tmp_path):
    """Models, State, Data plan, the palette and the help, by keys, before any fit."""
    config, _, _ = hidden_effect_case(shared_example, tmp_path)
    app = GcsApp(config)
    async with app.run_test(size=(120, 36)) as pilot:
        await settle(pilot)
        wb = app.workbench
        n_state = len(wb.analysis.problem.state)

        await pilot.press("2", "space")  # TAM1 model -> off
        await settle(pilot)
        assert wb.config.models["TAM1"] == "off"
        assert "TAM1" not in [s.name for s in wb.analysis.problem.sensors]
        await pilot.press("space")  # and back
        await settle(pilot)
        assert wb.config.models["TAM1"] == "magnetometer"
        assert len(wb.analysis.problem.state) == n_state

        await pilot.press("3")  # State: TAM1.align_1 held -> solve-for
        await settle(pilot)
        table = app.screen.query_one("#elements", DataTable)
        await pilot.press(*["down"] * table.get_row_index("TAM1.align_1"), "s")
        await settle(pilot)
        assert wb.config.state.elements["TAM1.align_1"].role == "solve-for"
        assert wb.analysis.problem.state["TAM1.align_1"].role == "solve-for"

        await pilot.press("4", "g", "enter", "m", "enter")  # a default gap and maneuver
        await settle(pilot)
        assert len(wb.config.prediction.gaps) == 1 and len(wb.config.prediction.maneuvers) == 1
        await pilot.press("e", "tab", "tab", "ctrl+u")
        await type_text(pilot, "30")
        await pilot.press("enter")
        await settle(pilot)
        assert wb.config.prediction.step == 30.0
        app.screen.query_one("#gaps", DataTable).focus()
        await pilot.press("d")
        assert wb.config.prediction.gaps == ()

        await pilot.press("ctrl+p")  # command palette
        await type_text(pilot, "view: residuals")
        await pilot.pause(0.5)
        await pilot.press("enter")
        await settle(pilot)
        assert isinstance(app.screen, ResidualsScreen)

        await pilot.press("question_mark")
        await pilot.pause()
        assert type(app.screen).__name__ == "HelpScreen"
        await pilot.press("escape", "q")
