"""One element, one unit and label in ``gcs predict``, ``gcs trade`` and ``gcs montecarlo``
(issue 24): all three take it from :mod:`gcs_core.display` (the one display rule), so a
dimensionless element has no unit (not ppm), a gyro drift reads deg/h², a rate deg/h."""

from __future__ import annotations

import re

import numpy as np
import pytest
from repo_paths import ROOT

from gcs_core.predictor.source import load_source
from gcs_core.trade.montecarlo import summarize, summary_lines
from gcs_core.trade.report import budget_lines
from gcs_core.trade.run import run_study
from gcs_core.trade.study import definition_from_config
from gcs_tui.cli.tables import prediction_table

ELEMENTS = ("TAM1.bias_x", "IRU.G_11", "IRU.bias_x", "IRU.bias_rate_x", "FHST1.scale_h")
EXPECTED = {
    "TAM1.bias_x": "nT",
    "IRU.G_11": "",
    "IRU.bias_x": "deg/h",
    "IRU.bias_rate_x": "deg/h²",
    "FHST1.scale_h": "",
}

CONFIG = f"""
[analysis]
mission = "{ROOT}/sample_data/missions/nominal-sunpoint"
[models]
FHST2 = "off"
FSS1 = "off"
CSS1 = "off"
[prediction]
start = 0.0
end = 600.0
step = 300.0
stars = "uniform"
[trade]
targets = {list(ELEMENTS)!r}
[trade.vary]
span_min = [10]
[trade.orbit]
a_km = 6898.137
e = 0.0012
i_deg = 28.5
raan_deg = 35.0
argp_deg = 60.0
mean_anomaly_deg = 10.0
"""


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    path = tmp_path_factory.mktemp("units") / "plan.toml"
    path.write_text(CONFIG.replace("'", '"'))
    src = load_source(path)
    pred = src.predict()
    rows = run_study(definition_from_config(src.config))
    rng = np.random.default_rng(7)
    recs = [
        {
            "status": "converged",
            "names": list(pred.names),
            "error": list(rng.standard_normal(len(pred.names)) * pred.noise_only),
            "P": pred.P.tolist(),
        }
        for _ in range(5)
    ]
    return prediction_table(pred), budget_lines(rows, 1), summary_lines(summarize(pred, recs))


def _predict_label(lines, name):
    line = next(ln for ln in lines if ln.startswith(name + " "))
    text = line[len(name) :].strip().split(" = ")[0].split("   ")[0].strip()
    parts = text.split(" ", 1)
    return parts[1] if len(parts) > 1 else ""


def _trade_label(lines, name):
    line = next(ln for ln in lines if ln.strip().startswith(name + " "))
    return re.search(r"σ\s+\S+\s+(.*?)\s*=", line).group(1).strip()


def _mc_label(lines, name):
    line = next(ln for ln in lines if ln.startswith(name + " "))
    tokens = line[len(name) :].split()
    # predicted σ, MC σ, ratio, fit σ, mean/σ, then the unit (none for a dimensionless one)
    return tokens[5] if len(tokens) > 5 and not tokens[5].startswith("(") else ""


@pytest.mark.parametrize("name", ELEMENTS)
def test_same_unit_and_label_in_predict_trade_and_montecarlo(outputs, name):
    pred, trade, mc = outputs
    labels = (_predict_label(pred, name), _trade_label(trade, name), _mc_label(mc, name))
    assert labels == (EXPECTED[name],) * 3, labels


def test_no_ppm_and_no_rad_per_s2_anywhere(outputs):
    text = "\n".join(line for lines in outputs for line in lines)
    assert "ppm" not in text and "rad/s" not in text
