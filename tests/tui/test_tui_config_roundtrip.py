"""A config saved from the TUI reproduces the TUI's numbers headless.

Keys only: open, fit, add the top candidate, edit one a-priori σ on the State screen,
refit, save the config (ctrl+s). Then ``Analysis(load_config(path)).fit()`` must give
every solve-for estimate and σ of the TUI's fit to 1e-9 relative.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_tui_pilot import hidden_effect_case, open_by_keys
from textual.widgets import DataTable
from tui_testing import settle, type_text

from gcs_core.config import load_config
from gcs_core.session import Analysis
from gcs_tui.tui.app import GcsApp

#: the σ typed into the State screen for TAM1.bias_x [nT]
NEW_SIGMA_NT = 150.0
EDITED = "TAM1.bias_x"


@pytest.mark.slow
async def test_saved_config_runs_headless_to_the_same_estimates(shared_example, tmp_path):
    config, hidden, _ = hidden_effect_case(shared_example, tmp_path)
    saved = tmp_path / "saved" / "from-tui.toml"
    app = GcsApp()
    async with app.run_test(size=(120, 36)) as pilot:
        await open_by_keys(pilot, config)
        await pilot.press("f")
        await settle(pilot)
        await pilot.press("7", "a")  # add the top candidate
        await settle(pilot)
        added = [s.effect for s in app.workbench.analysis.steps if s.action == "add"]

        await pilot.press("3")  # State & covariance
        await settle(pilot)
        table = app.screen.query_one("#elements", DataTable)
        target = table.get_row_index(EDITED)
        await pilot.press(*["down"] * (target - table.cursor_row))
        await pilot.press("e", "tab", "ctrl+u")  # edit, go to σ, clear it
        await type_text(pilot, f"{NEW_SIGMA_NT:g}")
        await pilot.press("enter")
        await settle(pilot)
        await pilot.press("f")  # refit from the edited config
        await settle(pilot)
        tui = app.workbench.result

        await pilot.press("ctrl+s", "ctrl+u")  # save the config
        await type_text(pilot, str(saved))
        await pilot.press("enter")
        await settle(pilot)
        await pilot.press("q")

    cfg = load_config(saved)
    assert cfg.state.elements[EDITED].sigma == NEW_SIGMA_NT
    headless = Analysis(cfg)
    assert added == [hidden] and hidden in headless.effects_in_state()
    res = headless.fit()
    assert res.solve_for == tui.solve_for
    np.testing.assert_allclose(res.x, tui.x, rtol=1e-9, atol=0.0)
    np.testing.assert_allclose(
        [res.sigma[n] for n in res.solve_for], [tui.sigma[n] for n in tui.solve_for], rtol=1e-9, atol=0.0
    )
    assert abs(res.chi2 - tui.chi2) <= 1e-9 * tui.chi2
