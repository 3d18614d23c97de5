"""``gcs fleet`` on a small simulated fleet (4 spacecraft × 2 days, gcs_core.fleet.simulate):

* a partial day, then the whole fleet: the partial day resumes (what was done is not redone);
* the malformed file is that spacecraft-day's one-line error and stops nothing else;
* the injected effect is discovered and the moved TAM bias is named (against the truth);
* each spacecraft's SCDS entry equals ``gcs batch --scds`` on the same inputs, its discovered
  effects ``gcs discover``'s, its §4.4 flag ``gcs verify``'s;
* re-running a finished fleet adds no entry;
* a task never reads the submitting machine's paths;
* the HTML report opens in headless Chromium with its table and trend plots.

One LocalCluster (2 workers on 127.0.0.1) serves every run of the module.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest
from browser import chromium, screenshot
from fleet_cases import local_cluster, small_fleet

from gcs_core.config import save_config
from gcs_core.fleet.html import render_html
from gcs_core.fleet.manifest import read_manifest
from gcs_core.fleet.report import build_report
from gcs_core.fleet.run import run_fleet
from gcs_core.fleet.store import FleetStore
from gcs_core.fleet.task import Job, run_job
from gcs_core.io import scds
from gcs_core.io.importer import load_mission
from gcs_tui.cli.commands import main

#: a LocalCluster's cold start (workers importing GCS) and eleven fits, ~25 s on idle cores:
#: marked slow (CI runs it; make quick skips it)
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    root = tmp_path_factory.mktemp("fleet")
    manifest, truth = small_fleet(root)
    m = read_manifest(manifest)
    with local_cluster(2) as (cluster, _client):
        addr = cluster.scheduler_address
        partial = run_fleet(m, days=["day1"], spacecraft=["SC01", "SC03"], scheduler=addr)
        full = run_fleet(m, scheduler=addr)
        store = FleetStore(m.output)
        before = {sc.name: [n for n, _ in store.calibrations(sc.name)] for sc in m.spacecraft}
        again = run_fleet(m, scheduler=addr)
        # a run stopped between the SCDS and the ASF appends: only the SCDS version is there
        cut = replace(m, output=root / "cut")
        (root / "cut" / "SC01").mkdir(parents=True)
        shutil.copy(store.scds_path("SC01"), FleetStore(cut.output).scds_path("SC01"))
        completed = run_fleet(cut, spacecraft=["SC01"], days=["day1"], scheduler=addr)
    report = build_report(m, full)
    return {
        "root": root,
        "m": m,
        "truth": truth,
        "partial": partial,
        "full": full,
        "again": again,
        "completed": completed,
        "before": before,
        "report": report,
        "store": store,
    }


def _malformed(truth):
    return {
        (sc, day): rec["malformed"]
        for sc, r in truth["spacecraft"].items()
        for day, rec in r["days"].items()
        if rec["malformed"]
    }


def test_the_run_completes_and_lists_the_malformed_input_with_its_one_line_error(fleet):
    full, truth = fleet["full"], fleet["truth"]
    bad = _malformed(truth)
    assert bad  # the simulated fleet has one
    states = {(e.spacecraft, e.day): e for e in full.entries}
    assert len(states) == 4 * 2
    for key, e in states.items():
        if key in bad:
            where = bad[key]
            assert e.state == "error"
            assert f"{where['file']}:{where['line']}:2" in e.error and "'bx'" in e.error
            assert "\n" not in e.error
        else:
            assert e.state in ("calibrated", "already done"), (key, e.error)
    assert [(x["spacecraft"], x["day"]) for x in fleet["report"]["errors"]] == list(bad)


def test_a_partial_day_resumes_without_redoing_what_was_done(fleet):
    partial, full = fleet["partial"], fleet["full"]
    assert sorted((e.spacecraft, e.state) for e in partial.entries) == [("SC01", "calibrated"), ("SC03", "calibrated")]
    for e in partial.entries:
        again = full.entry(e.spacecraft, e.day)
        assert again.state == "already done" and again.scds_version == e.scds_version
    # every computed spacecraft-day holds exactly one SCDS version and one ASF solution
    store = fleet["store"]
    for sc in fleet["m"].spacecraft:
        days = [p["fleet"]["day"] for _, p in store.calibrations(sc.name)]
        assert len(days) == len(set(days))
        assert [p["fleet"]["day"] for _, p in store.attitudes(sc.name)] == days


def test_an_scds_version_without_its_asf_solution_gets_only_the_asf_solution(fleet):
    (e,) = fleet["completed"].entries
    assert e.state == "completed" and e.scds_version == 1 and e.asf_solution == 1
    cut = FleetStore(fleet["root"] / "cut")
    assert [n for n, _ in cut.calibrations("SC01")] == [1, 2]  # the copied history, nothing added
    ((n, prov),) = cut.attitudes("SC01")
    assert prov["scds_version"] == 1 and prov["fleet"]["day"] == "day1"


def test_rerunning_a_finished_fleet_adds_no_entry(fleet):
    again, store = fleet["again"], fleet["store"]
    assert {e.state for e in again.entries} == {"already done", "error"}
    assert again.workers == 0  # nothing to compute: no task was submitted
    after = {sc.name: [n for n, _ in store.calibrations(sc.name)] for sc in fleet["m"].spacecraft}
    assert after == fleet["before"]


def test_the_injected_effect_and_the_moved_bias_are_named(fleet):
    report, truth = fleet["report"], fleet["truth"]
    injected = {
        (sc, day): {i["effect"] for i in rec["injected"] if not i.get("moved")}
        for sc, r in truth["spacecraft"].items()
        for day, rec in r["days"].items()
        if not rec["malformed"]
    }
    found = {(d["spacecraft"], d["day"]) for d in report["discovered"]}
    for key, effects in injected.items():
        for eff in effects:
            assert {"spacecraft": key[0], "day": key[1], "effect": eff} in report["discovered"]
    assert found == {k for k, v in injected.items() if v}  # and nothing on the clean ones
    moved_truth = {
        (sc, day)
        for sc, r in truth["spacecraft"].items()
        for day, rec in r["days"].items()
        if any(i.get("moved") for i in rec["injected"])
    }
    moved = {(x["spacecraft"], x["day"]): set() for x in report["moved"]}
    for x in report["moved"]:
        moved[(x["spacecraft"], x["day"])].add(x["element"])
    # the spacecraft with a hidden effect fit "model inadequate": never an accepted baseline
    assert set(moved) == moved_truth
    for elements in moved.values():
        assert elements == {"TAM1.bias_x", "TAM1.bias_y", "TAM1.bias_z"}


def test_each_result_equals_gcs_batch_discover_and_verify_on_the_same_inputs(fleet, tmp_path, capsys):
    m, store = fleet["m"], fleet["store"]
    sc, day = m.spacecraft_named("SC02"), "day1"
    cfg_path = save_config(m.config(sc, day), tmp_path / "sc02.toml")
    scds_path = tmp_path / "single.scds.h5"
    assert main(["batch", str(cfg_path), "--scds", str(scds_path), "--progress", "off"]) == 0
    single = scds.read_version(scds_path, 1)
    n = next(n for n, p in store.calibrations("SC02") if p["fleet"]["day"] == day)
    fleet_v = scds.read_version(store.scds_path("SC02"), n)
    assert fleet_v.params == single.params  # bit for bit
    assert fleet_v.element_names == single.element_names
    np.testing.assert_array_equal(fleet_v.covariance, single.covariance)
    skip = {"created_utc", "gcs_version", "note", "fleet"}
    assert {k: v for k, v in fleet_v.provenance.items() if k not in skip} == {
        k: v for k, v in single.provenance.items() if k not in skip
    }
    facts = fleet_v.provenance["fleet"]
    rep = tmp_path / "discover.json"
    assert (
        main(["discover", str(cfg_path), "--max-steps", str(m.max_steps), "--report", str(rep), "--progress", "off"])
        == 0
    )
    added = [s["added"] for s in json.loads(rep.read_text())["steps"] if s.get("action") == "add"]
    assert added == facts["discovered"] and added
    assert main(["verify", str(cfg_path), "--progress", "off"]) == (1 if facts["flag"] else 0)
    capsys.readouterr()


def test_a_task_never_reads_the_submitters_paths(fleet, tmp_path):
    m, store = fleet["m"], fleet["store"]
    sc = m.spacecraft_named("SC01")
    here = tmp_path / "SC01-day1"
    shutil.copytree(m.mission_dir(sc, "day1"), here)
    cfg = m.config(sc, "day1")
    job = Job("SC01", "day1", "h", replace(cfg, mission=here), load_mission(here), discover=False)
    here.rename(tmp_path / "gone")  # the data left this machine's path
    out = run_job(job)
    assert out.error is None
    n = next(n for n, p in store.calibrations("SC01") if p["fleet"]["day"] == "day1")
    assert out.calibration["sensor_params"] == scds.read_version(store.scds_path("SC01"), n).params


def test_the_html_report_opens_in_headless_chromium_with_its_table_and_trends(fleet, tmp_path):
    browser = chromium()
    if browser is None:
        pytest.skip("no Chromium: `make test` installs it with apt-get (apt-get install chromium)")
    image = pytest.importorskip("PIL.Image")
    page = tmp_path / "fleet.html"
    page.write_text(render_html(fleet["report"]))
    png = tmp_path / "fleet.png"
    run = screenshot(browser, page, png, width=1200, height=4000, timeout=90)
    assert png.is_file(), run.stderr[-2000:]
    img = np.asarray(image.open(png).convert("RGB")).astype(int)

    def pixels(rgb, tol=4):
        return int(np.all(np.abs(img - np.array(rgb)) <= tol, axis=2).sum())

    # the status table: rows of each state's colour (.ok, .flag, .err)
    assert pixels((0xD8, 0xF0, 0xD8)) > 5000 and pixels((0xF8, 0xE0, 0xA0)) > 5000 and pixels((0xF4, 0xC0, 0xC0)) > 2000
    # the trend plots: grey series for most spacecraft, the moved one (SC03) in colour
    assert pixels((0x9A, 0x9A, 0x9A), tol=20) > 2000
    assert pixels((0xC0, 0x39, 0x2B), tol=30) > 50


def test_gcs_fleet_writes_its_reports_and_aems_and_exits_1_on_findings(fleet, tmp_path, capsys):
    """The command on the finished fleet: nothing to compute (no cluster), the table, the
    reports, one AEM per stored day that reads back to its ASF solution within 1e-12."""
    pytest.importorskip("ccsds_ndm")
    from gcs_core.fleet.ccsds import read_aem
    from gcs_core.io import asf
    from gcs_core.io.importer import load_mission

    m = fleet["m"]
    report, page, aem = tmp_path / "r.json", tmp_path / "r.html", tmp_path / "aem"
    code = main(
        ["fleet", str(m.path), "--report", str(report), "--html", str(page), "--aem", str(aem), "--progress", "off"]
    )
    out = capsys.readouterr().out
    assert code == 1  # a malformed file, a flag, a moved bias: findings to act on
    assert "SC04" in out and "not a number" in out and "moved TAM1.bias" in out
    assert json.loads(report.read_text())["fleet"] == m.name and page.read_text().startswith("<!DOCTYPE html>")
    files = sorted(aem.glob("*.aem.xml"))
    assert len(files) == 7
    store = fleet["store"]
    epoch = load_mission(m.mission_dir(m.spacecraft_named("SC03"), "day2")).spec.epoch
    n = next(n for n, p in store.attitudes("SC03") if p["fleet"]["day"] == "day2")
    sol = asf.read_solution(store.asf_path("SC03"), n)
    t, q = read_aem(aem / "SC03-day2.aem.xml", epoch)
    assert np.max(np.abs(q - sol.q)) <= 1e-12 and np.max(np.abs(t - sol.t)) <= 1e-12
