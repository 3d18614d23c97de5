"""The correlation-robust σ in the product: ``gcs batch``'s JSON report and state table.

The laboratory mission of ``test_sigma_scale`` (exact kinematics, a field gradient, 60 s)
run through the command with ``--sigma-window 1`` (60 windows; the default 4 s leaves 15,
fewer than MIN_BLOCKS, and the scale is skipped with one log line). With each magnetometer
draw held over :data:`HOLD` samples the report gives the magnetometer's elements the data
set scales near ``sqrt(HOLD)`` (those the a priori sets, near 1: test_sigma_scale) and σ ×
scale, and the table lists them under "σ with the residuals' correlation"; with white noise
the scales sit at 1 within their scatter and the table adds nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import logging

import numpy as np
import pytest
from test_field_gradient import EFFECTS, fit, write_mission
from test_ground_mission import MEMS_PRIORS
from test_sigma_scale import DATA_SET, HOLD, MAG_ELEMENTS, PRIOR_SET, SCALE_SCATTER

from gcs_core.config import default_config, save_config
from gcs_tui.cli.arguments import seconds_or_zero
from gcs_tui.cli.commands import EXIT_OK, main
from gcs_tui.cli.tables import HEADER_SIGMA_SCALE as HEADER

#: 1-s windows: 60 over the 60-s span
WINDOW_S = 1.0


@pytest.fixture(scope="module", params=[1, HOLD], ids=["white", "held"])
def batch(request, tmp_path_factory):
    """``gcs batch`` on the mission: (hold, stdout, report)."""
    tmp = tmp_path_factory.mktemp(f"report-hold{request.param}")
    root = write_mission(tmp / "mission", np.random.default_rng(7), hold=request.param)
    cfg = default_config(root).with_changes(
        physics={"field_model": "constant"},
        state={"attitude_sigma_deg": 10.0, "effects": EFFECTS + ("MAG.field_gradient",), "elements": MEMS_PRIORS},
        filter={"noise_weighting": "stated"},  # the sandwich judges the white-noise fit's σ
    )
    path = save_config(cfg, tmp / "lab.toml")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["-q", "batch", str(path), "--sigma-window", f"{WINDOW_S:g}", "--report", str(tmp / "r.json")])
    assert code == EXIT_OK
    return request.param, out.getvalue(), json.loads((tmp / "r.json").read_text())


def test_report_gives_each_element_its_scale_and_sigma(batch):
    hold, _, rep = batch
    sc = rep["sigma_scale"]
    assert (sc["window_s"], sc["n_windows"], sc["sensors"]) == (WINDOW_S, 60, ["MAG", "OPT"])
    assert min(sc["frames_per_window"].values()) > 2  # samples at 50 Hz: each window sees the correlation
    elements = sc["elements"]
    for n in MAG_ELEMENTS:
        expected = np.sqrt(hold) if n not in PRIOR_SET else 1.0
        e = elements[n]
        assert abs(e["scale"] / expected - 1.0) < SCALE_SCATTER, (n, e["scale"], expected)
        assert e["sigma_with_correlation"] == pytest.approx(e["sigma"] * max(1.0, e["scale"]), rel=1e-3)
    sigma = {row["name"]: row["sigma"] for row in rep["state"]}
    assert all(e["sigma"] == pytest.approx(sigma[n]) for n, e in elements.items())


def test_table_lists_the_correlated_elements_only(batch):
    hold, out, rep = batch
    if hold == 1:  # white: the scales are within their scatter of 1, nothing is added
        assert HEADER not in out
        assert max(e["scale"] for e in rep["sigma_scale"]["elements"].values()) < rep["sigma_scale"]["flag_above"]
        return
    block = out[out.index(HEADER) :].splitlines()
    assert block[0].endswith(f"({'batch-means sandwich'}, 1-s windows, 60 windows):")
    listed = {line.split()[0]: float(line.split()[2]) for line in block[1:] if line.startswith("  ")}
    assert set(DATA_SET) <= set(listed)
    for n in DATA_SET:
        assert listed[n] == pytest.approx(rep["sigma_scale"]["elements"][n]["scale"], abs=0.006)
    assert "OPT.time_offset" not in listed  # the optical reference's noise is white
    assert "samples per" not in out  # many samples per window


def test_the_default_window_fits_the_span_and_the_sampling(tmp_path, caplog):
    """The default window: 4 s leaves 15 windows on the 60-s span, so it is shortened to
    leave MIN_BLOCKS + 1 (logged: longer correlation is not seen); one of 4 s is refused
    (too few windows); 0 is off; a span too short for windows of ten samples has none."""
    from types import SimpleNamespace

    from gcs_core.diagnosis.honest_sigma import auto_window
    from gcs_core.noise.correlation import MIN_BLOCKS
    from gcs_core.noise.weighting import MIN_SAMPLES

    root = write_mission(tmp_path, np.random.default_rng(8))
    a, _ = fit(root, EFFECTS)
    with caplog.at_level(logging.INFO, logger="gcs_core.diagnosis.honest_sigma"):
        sc = a.sigma_scale()
    assert sc is not None and sc.n_blocks >= MIN_BLOCKS and sc.block_s < 4.0, sc
    assert [r.getMessage() for r in caplog.records if "a short span" in r.getMessage()]
    a.sigma_window = 4.0
    assert a.sigma_scale() is None  # 15 < MIN_BLOCKS
    a.sigma_window = 0.0
    assert a.sigma_scale() is None
    a.sigma_window = WINDOW_S
    assert a.sigma_scale().n_blocks == 60
    # sparse sampling: the window holds MIN_SAMPLES samples (5-s samples: 50 s)
    sparse = SimpleNamespace(residuals={"MAG": SimpleNamespace(t=np.arange(0.0, 36000.0, 5.0), used=np.ones(7200))})
    assert auto_window(sparse) == MIN_SAMPLES * 5.0
    short = SimpleNamespace(residuals={"MAG": SimpleNamespace(t=np.arange(0.0, 500.0, 5.0), used=np.ones(100))})
    assert auto_window(short) is None


def test_window_option_refuses_bad_values():
    assert seconds_or_zero("0") == 0.0
    for bad in ("-1", "inf", "nan", "four"):
        with pytest.raises(argparse.ArgumentTypeError):
            seconds_or_zero(bad)


def test_one_sample_per_window_is_said():
    """Windows shorter than the sampling interval see no correlation: the table says so."""
    from types import SimpleNamespace

    from gcs_core.noise.correlation import SigmaScale
    from gcs_tui.cli.tables import sigma_scale_lines

    sc = SigmaScale(("MAG",), 4.0, 100, {"MAG.bias_x": 7.0, "MAG.bias_y": 1.1})
    res = SimpleNamespace(
        carries_process_noise=False,
        residuals={"MAG": SimpleNamespace(used=np.ones(100, bool))},
        sigma={"MAG.bias_x": 5.0, "MAG.bias_y": 5.0},
        state={n: SimpleNamespace(value=1.0, unit="nT") for n in sc.scale},
    )
    lines = sigma_scale_lines(SimpleNamespace(result=res, sigma_scale=lambda: sc))
    assert lines[0].startswith(HEADER) and "4-s windows, 100 windows" in lines[0]
    assert [ln.split()[0] for ln in lines[1:] if ln.startswith("  ")] == ["MAG.bias_x"]
    assert "35 nT" in lines[1]  # σ 5 × scale 7
    assert "fewer than two samples per 4-s window" in " ".join(lines)
