"""Trade studies: results file, resume after a real kill, and identical numbers on Dask.

* A study killed mid-run (SIGKILL of the ``gcs trade`` process) leaves an HDF5 file whose
  every finished plan is readable; ``--resume`` computes only the missing plans, and the
  whole study then equals an uninterrupted one number for number.
* Ctrl-C (SIGINT) stops the run with exit code 130, keeping the finished plans.
* The same study serially and on a 2-worker ``LocalCluster`` gives identical numbers.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from repo_paths import ROOT

from gcs_core.config import load_config
from gcs_core.errors import InputError
from gcs_core.trade import run as trade_run
from gcs_core.trade import store
from gcs_core.trade.run import read_study, run_study
from gcs_core.trade.space import parse_values, parse_vary
from gcs_core.trade.study import definition_from_config

CONFIG = ROOT / "sample_data" / "trade" / "smm-tam-bias.toml"
#: the kill test's study: 2 spans × 48 starts = 96 short plans (a few seconds serially,
#: written at least once a second)
KILL_VARY = ["span_min=10,20", "start_min=0:94:2"]


def _defn(vary):
    return definition_from_config(load_config(CONFIG), parse_vary(vary))


def _numbers(rows):
    return [(r.index, r.plan_id, r.sigma, r.noise_only, r.status) for r in rows]


def _gcs(args, **kw):
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    return subprocess.Popen(
        [sys.executable, "-m", "gcs_tui.cli", *args],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kw,
    )


def _wait_for_rows(path: Path, proc, minimum: int = 1, timeout: float = 60.0) -> int:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if path.exists():
            try:
                n = len(read_study(path)[1])
            except Exception:  # noqa: BLE001 — a file being replaced: look again
                n = 0
            if n >= minimum:
                return n
        if proc.poll() is not None:
            break
        time.sleep(0.05)
    return 0


def test_parse_values():
    assert parse_values("0:90:30", "k") == (0, 30, 60, 90)
    assert parse_values("roll,yaw", "k") == ("roll", "yaw")
    assert parse_values("1.5,2", "k") == (1.5, 2)
    with pytest.raises(InputError, match="trade.vary.k"):
        parse_values("5:0:1", "trade.vary.k")


@pytest.mark.slow
def test_killed_study_keeps_finished_plans_and_resume_computes_the_rest(tmp_path, monkeypatch):
    out = tmp_path / "study.h5"
    args = ["trade", str(CONFIG), "--output", str(out), "--progress", "plain"]
    for v in KILL_VARY:
        args += ["--vary", v]
    proc = _gcs(args)
    kept = _wait_for_rows(out, proc)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert kept > 0, proc.stderr.read()
    defn, rows = read_study(out)  # every finished plan readable
    total = len(_defn(KILL_VARY).combos())
    assert 0 < len(rows) < total, "the kill came too late to test anything"
    assert all(r.status == "ok" for r in rows)

    computed = []
    real = trade_run.evaluate_plans

    def counting(defn, items):
        computed.extend(i for i, _ in items)
        return real(defn, items)

    monkeypatch.setattr(trade_run, "evaluate_plans", counting)
    resumed = run_study(_defn(KILL_VARY), out, resume=True)
    assert sorted(computed) == sorted(set(range(total)) - {r.index for r in rows})
    assert len(resumed) == total
    monkeypatch.setattr(trade_run, "evaluate_plans", real)
    sample = [r.index for r in rows[:3]] + sorted(computed)[:3]  # written before and after
    fresh = {
        r.index: r
        for r in trade_run.evaluate_plans(_defn(KILL_VARY), [(i, _defn(KILL_VARY).combos()[i]) for i in sample])
    }
    assert _numbers([resumed[i] for i in sample]) == _numbers([fresh[i] for i in sample])


def test_interrupt_exits_130_and_keeps_rows(tmp_path):
    out = tmp_path / "study.h5"
    args = ["trade", str(CONFIG), "--output", str(out), "--progress", "plain"]
    for v in KILL_VARY:
        args += ["--vary", v]
    proc = _gcs(args)
    _wait_for_rows(out, proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the study finished before the interrupt")
    assert proc.returncode == 130, err
    assert "--resume" in err
    assert len(read_study(out)[1]) > 0


def test_output_refused_without_resume_and_other_study(tmp_path):
    out = tmp_path / "s.h5"
    run_study(_defn(["span_min=10", "start_min=0"]), out)
    with pytest.raises(InputError, match="--resume"):
        run_study(_defn(["span_min=10", "start_min=0"]), out)
    with pytest.raises(InputError, match="another study"):
        run_study(_defn(["span_min=20", "start_min=0"]), out, resume=True)
    head, recs = store.read(out, store.TRADE)
    assert head["study_digest"] and len(recs) == 1


def test_serial_path_never_imports_dask(tmp_path):
    code = (
        "import sys; from gcs_core.config import load_config; from gcs_core.trade.study import "
        "definition_from_config; from gcs_core.trade.run import run_study; "
        f"run_study(definition_from_config(load_config({str(CONFIG)!r}), {{'span_min': (10,)}})); "
        "print('dask' in sys.modules, 'distributed' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        timeout=120,
    )
    assert out.stdout.split() == ["False", "False"], out.stderr


@pytest.mark.slow
def test_identical_numbers_serially_and_on_a_local_cluster(tmp_path):
    pytest.importorskip("distributed")
    vary = ["span_min=10,20", "start_min=0,30"]
    serial = run_study(_defn(vary))
    dask = run_study(_defn(vary), tmp_path / "d.h5", workers=2, batch=1)
    assert _numbers(serial) == _numbers(dask)
