"""The State screen's element details give the σ with the residuals' correlation where it
clearly inflates the fit's σ (:mod:`gcs_core.diagnosis.honest_sigma`), on the bundled BROAD
sample (real data: Laidig et al., Data 6(7), 2021, doi:10.3390/data6070072, CC BY 4.0),
and nothing where the residuals are white."""

from __future__ import annotations

import pytest
from repo_paths import ROOT
from textual.widgets import DataTable, Static
from tui_testing import settle

from gcs_core.diagnosis.honest_sigma import flagged
from gcs_tui.tui.app import GcsApp
from gcs_tui.tui.workbench import Workbench

NOTE = "with the residuals' correlation"


async def _detail_after_fit(config, tmp_path, element: str) -> tuple[str, dict]:
    wb = Workbench.open(config, save_path=tmp_path / "a.toml", scds_path=tmp_path / "h.scds.h5")
    app = GcsApp(workbench=wb, start_view="state")
    async with app.run_test(size=(160, 44)) as pilot:
        await settle(pilot)
        await pilot.press("f")
        await settle(pilot)
        table = app.screen.query_one("#elements", DataTable)
        table.move_cursor(row=table.get_row_index(element))
        await pilot.pause()
        app.screen._detail()
        text = str(app.screen.query_one("#element-detail", Static).render())
        return text, flagged(wb.analysis.sigma_scale())


async def test_correlated_residuals_widen_the_sigma_shown(tmp_path):
    config = ROOT / "sample_data/configs/real-broad-02-slow-rotation.toml"
    if not config.is_file():
        pytest.skip("the BROAD sample mission is not bundled")
    text, scales = await _detail_after_fit(config, tmp_path, "MAG.bias_z")
    assert "MAG.bias_z" in scales, scales
    assert f"{NOTE} (×{scales['MAG.bias_z']:.2f})" in text, text


async def test_white_residuals_add_nothing(shared_example, tmp_path):
    text, scales = await _detail_after_fit(shared_example("sunpoint-nominal"), tmp_path, "TAM1.bias_x")
    assert not scales and NOTE not in text and "estimate" in text, text
