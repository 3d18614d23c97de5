"""The Trade screen: a snapshot from a small trade study, and opening a plan in the Data
plan screen (the plan's span and gaps become the config's ``[prediction]`` plan)."""

from __future__ import annotations

import pytest
from repo_paths import ROOT
from tui_testing import sample_mission, settle

from gcs_core.config import load_config
from gcs_core.trade.run import run_study
from gcs_core.trade.study import definition_from_config
from gcs_tui.tui.app import GcsApp
from gcs_tui.tui.screens.trade import TradeScreen
from gcs_tui.tui.workbench import Workbench

CONFIG = ROOT / "sample_data" / "trade" / "smm-tam-bias.toml"


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("trade") / "study.h5"
    cfg = load_config(CONFIG)
    run_study(
        definition_from_config(
            cfg, {"passes": (1, 2), "pass_min": (10,), "separation_min": (30,), "start_min": (0, 20, 40)}
        ),
        out,
    )
    return out


@pytest.fixture(scope="module")
def workbench():
    mission = sample_mission("nominal-sunpoint")
    if mission is None:
        pytest.skip("sample_data/missions/nominal-sunpoint is not generated")
    return Workbench.open(mission)


def test_trade_screen(snap_compare, study, workbench):
    """The ranked plans of the study, σ of TAM1.bias_x against the pass start."""

    async def show(pilot):
        await settle(pilot)
        pilot.app.open_trade(study)
        await pilot.pause()

    app = GcsApp(workbench=workbench, start_view="plan")
    assert snap_compare(app, terminal_size=(120, 36), run_before=show)


async def test_open_plan_in_data_plan_screen(study, workbench):
    app = GcsApp(workbench=workbench, start_view="mission")
    async with app.run_test(size=(120, 36)) as pilot:
        await settle(pilot)
        assert app.open_trade(study)
        await pilot.pause()
        screen = app.screen
        assert isinstance(screen, TradeScreen)
        best = screen.ranked[0][1]
        await pilot.press("enter")
        await pilot.pause()
        assert app.current_mode == "plan"
        cfg = app.workbench.config
        assert (cfg.prediction.start, cfg.prediction.end) == (best.description["start"], best.description["end"])
        assert [list(g) for g in cfg.prediction.gaps] == best.description["gaps"]
