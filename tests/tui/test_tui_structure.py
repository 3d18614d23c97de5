"""The residual-structure list (issue 26): from Diagnosis, ``y`` lists what the residuals
follow, and selecting one plots that residual against the channel."""

from __future__ import annotations

import pytest
from textual.widgets import DataTable
from tui_testing import sample_mission, settle

from gcs_core.config import save_config
from gcs_core.config_schema import AnalysisConfig
from gcs_tui.tui.app import GcsApp
from gcs_tui.tui.screens.diagnosis import DiagnosisScreen
from gcs_tui.tui.screens.structure import StructureScreen


def _app(tmp_path) -> GcsApp:
    """The app on the hidden-contamination sample (skipped when it is not bundled)."""
    mission = sample_mission("hidden-tam-contamination")
    if mission is None:
        pytest.skip("sample mission not bundled")
    return GcsApp(save_config(AnalysisConfig().with_changes(mission=mission), tmp_path / "analysis.toml"))


async def _fit_then_diagnosis(pilot) -> None:
    await settle(pilot)
    await pilot.press("f")  # fit
    await settle(pilot)
    await pilot.press("7")  # diagnosis
    await settle(pilot)


@pytest.mark.slow
async def test_dependencies_listed_and_plotted(tmp_path):
    app = _app(tmp_path)
    async with app.run_test(size=(120, 36)) as pilot:
        await _fit_then_diagnosis(pilot)
        assert isinstance(app.screen, DiagnosisScreen)
        await pilot.press("y")
        await settle(pilot)
        screen = app.screen
        assert isinstance(screen, StructureScreen)
        table = screen.query_one("#deps", DataTable)
        assert table.row_count > 0
        first = screen.deps[0]
        assert (first.sensor, first.channel) == ("TAM1", "aux:mtb_x")  # the hidden contamination's channel
        await pilot.press("down")
        await settle(pilot)
        assert screen.query_one("#dep-plot")._painter is not None
        await pilot.press("escape")
        await settle(pilot)
        assert isinstance(app.screen, DiagnosisScreen)


@pytest.mark.slow
async def test_family_candidates_listed_with_the_catalogue_ones(tmp_path):
    """After a fit, the candidate table lists the families of what the residuals follow (the
    hidden contamination's channel, the orbit) beside the catalogue's effects, as discovery
    offers them."""
    app = _app(tmp_path)
    async with app.run_test(size=(120, 36)) as pilot:
        await _fit_then_diagnosis(pilot)
        table = app.screen.query_one("#candidates", DataTable)
        keys = [str(k.value) for k in table.rows]
        assert "TAM1.contamination_mtb_x" in keys  # the catalogue's
        assert "TAM1.scale_vs_mtb_x" in keys  # a family on the channel the search found
