"""SVG snapshots of every GCS screen at 80×24 (compact) and 160×48, drawn from the
bundled sample mission ``hidden-tam-contamination`` after the analyst's session:
first fit, the top candidate added, a refit from the config, a prediction, a
verification, and two calibration versions in an SCDS (before and after the effect).

The state is computed once per module and shown by every app; snapshots wait for the
workers (``settle``) so nothing is caught half-drawn. Update with
``pytest tests/tui/test_tui_snapshots.py --snapshot-update`` and look at the SVGs.
"""

from __future__ import annotations

import pytest
from tui_testing import sample_mission, settle

from gcs_core.io import h5store
from gcs_tui.tui import filtr_run, jobs
from gcs_tui.tui.app import GcsApp
from gcs_tui.tui.keys import VIEWS
from gcs_tui.tui.workbench import Workbench

MISSION = "hidden-tam-contamination"
SIZES = {"80x24": (80, 24), "160x48": (160, 48)}
#: what the SCDS records as creation time and version, fixed so the snapshots are stable
FIXED_UTC = ("2024-05-15T09:00:00Z", "2024-05-15T09:30:00Z")


@pytest.fixture(scope="module")
def workbench(tmp_path_factory) -> Workbench:
    mission = sample_mission(MISSION)
    if mission is None:
        pytest.skip(f"sample_data/missions/{MISSION} is not generated")
    tmp = tmp_path_factory.mktemp("tui-snap")
    wb = Workbench.open(mission, save_path=tmp / "analysis.toml", scds_path=tmp / "history.scds.h5")
    wb.fit()
    now = [FIXED_UTC[0]]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(h5store, "utc_now", lambda: now[0])
        mp.setattr(h5store, "gcs_version", lambda: "0.1.0")
        jobs.save_calibration(wb, note="first fit")
        top = next(c for c in wb.analysis.candidates if c.identifiable)
        wb.change_effect(top.id, True)
        wb.fit()  # refit from the config, as the analyst does (f)
        now[0] = FIXED_UTC[1]
        jobs.save_calibration(wb, note=f"+{top.id}")
    jobs.predict(wb)
    jobs.verify(wb)
    filtr_run.advance(wb, None)
    return wb


@pytest.mark.parametrize("size", list(SIZES))
@pytest.mark.parametrize("view", [mode for mode, *_ in VIEWS])
def test_screen(snap_compare, workbench, view, size):
    """One GCS screen on the sample mission after adding the top candidate."""
    app = GcsApp(workbench=workbench, start_view=view)
    assert snap_compare(app, terminal_size=SIZES[size], run_before=settle)


def test_help_screen(snap_compare, workbench):
    """The key help over the Diagnosis screen (every key the app and the screen know)."""
    app = GcsApp(workbench=workbench, start_view="diagnosis")
    assert snap_compare(app, terminal_size=SIZES["80x24"], run_before=settle, press=["question_mark"])


def test_diagnosis_explanation_scrolled_at_80x24(snap_compare, workbench):
    """At 80×24 the explanation pane scrolls: its end (estimates, MDB, aliases, the rule)."""
    app = GcsApp(workbench=workbench, start_view="diagnosis")
    assert snap_compare(app, terminal_size=SIZES["80x24"], run_before=settle, press=["tab", "end"])


def test_state_details_at_80x24(snap_compare, workbench):
    """At 80×24 `i` shows the selected element's details under the table."""
    app = GcsApp(workbench=workbench, start_view="state")
    assert snap_compare(app, terminal_size=SIZES["80x24"], run_before=settle, press=["i"])


def test_residuals_against_a_torquer_channel(snap_compare, workbench):
    """Residual against the channel mtb_x: binned means with error bars, the channel's unit."""
    app = GcsApp(workbench=workbench, start_view="residuals")
    assert snap_compare(app, terminal_size=SIZES["160x48"], run_before=settle, press=["x"] * 5)


def test_diagnosis_charts_at_80x24(snap_compare, workbench):
    """At 80×24 `g` shows the RMS-per-step charts: titles, round ticks, the legend line."""
    app = GcsApp(workbench=workbench, start_view="diagnosis")
    assert snap_compare(app, terminal_size=SIZES["80x24"], run_before=settle, press=["g"])


def test_residuals_against_a_torquer_channel_at_80x24(snap_compare, workbench):
    """At 80×24 the binned means are printed as numbers beside the channel plot."""
    app = GcsApp(workbench=workbench, start_view="residuals")
    assert snap_compare(app, terminal_size=SIZES["80x24"], run_before=settle, press=["x"] * 5)


@pytest.mark.parametrize("view", [mode for mode, *_ in VIEWS])
async def test_titles_legends_and_tab_names_at_80x24(workbench, view):
    """At 80×24 every tab name is in the bar and every plot drawn shows its title (which
    carries its legend) on its first line — plotext used to drop a title wider than the plot."""
    from gcs_tui.tui.widgets.chrome import NavBar
    from gcs_tui.tui.widgets.plots import MIN_HEIGHT, MIN_WIDTH, GcsPlot

    app = GcsApp(workbench=workbench, start_view=view)
    async with app.run_test(size=SIZES["80x24"]) as pilot:
        await settle(pilot)
        bar = app.screen.query_one(NavBar).render().plain
        for _, key, _, short in VIEWS:
            assert f"{key} {short}" in bar, bar
        for plot in app.screen.query(GcsPlot):
            if not plot.display or plot.size.width < MIN_WIDTH or plot.size.height < MIN_HEIGHT:
                continue
            first = plot.render().plain.splitlines()[0]
            assert first.strip() and not first.lstrip().startswith(("┌", "│")), (plot.id, first)
