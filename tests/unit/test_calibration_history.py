"""Calibration writes (seed §3.2.2 DRIVER): SCDS versions and ASF solutions from a fit.

Two saves give versions 1 and 2; the history is append-only (version 1 reads back
byte-for-byte the same after version 2 is written); the diff names what changed.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from gcs_core.calibration import save_calibration, save_ground_attitude
from gcs_core.config_schema import AnalysisConfig
from gcs_core.errors import EstimationError
from gcs_core.io import asf, scds
from gcs_core.session import Analysis


@pytest.fixture(scope="module")
def fitted(example_dir):
    """sunpoint-nominal fitted with the seed state, and again with TAM1.alignment added."""
    first = Analysis(AnalysisConfig(mission=example_dir).with_changes(diagnosis={"holdout_fraction": 0.0}))
    first.fit(holdout=False)
    second = copy.copy(first)
    second.steps = list(first.steps)
    second.add_effect("TAM1.alignment")
    return first, second


def _snapshot(path, n):
    v = scds.read_version(path, n)
    return dict(v.params), v.element_names, None if v.covariance is None else v.covariance.copy(), dict(v.provenance)


def test_two_saves_make_versions_one_and_two_and_history_is_append_only(fitted, tmp_path):
    first, second = fitted
    path = tmp_path / "scds.h5"
    assert save_calibration(first, path, note="seed state") == 1
    before = _snapshot(path, 1)
    assert save_calibration(second, path, note="with TAM1 alignment") == 2
    after = _snapshot(path, 1)
    assert before[0] == after[0] and before[1] == after[1] and before[3] == after[3]
    np.testing.assert_array_equal(before[2], after[2])
    versions = scds.list_versions(path)
    assert [v.version for v in versions] == [1, 2]
    assert [v.note for v in versions] == ["seed state", "with TAM1 alignment"]
    assert scds.read_version(path).version == 2

    diff = {row[0]: row for row in scds.diff_versions(path, 1, 2)}
    for k in (1, 2, 3):  # new in version 2
        name = f"TAM1.align_{k}"
        assert math.isnan(diff[name][1]) and math.isfinite(diff[name][2])
    assert diff["TAM1.bias_x"][3] == pytest.approx(
        second.result.state["TAM1.bias_x"].value - first.result.state["TAM1.bias_x"].value, abs=1e-12
    )


def test_version_holds_values_sigmas_covariance_and_provenance(fitted, tmp_path):
    first, _ = fitted
    res = first.result
    path = tmp_path / "scds.h5"
    save_calibration(first, path, note="check")
    v = scds.read_version(path, 1)
    held = {e.name for e in res.state if e.role == "held"}
    assert set(v.params) == {e.name for e in res.state} - held
    for name in res.solve_for:
        value, sigma, unit = v.params[name]
        assert value == res.state[name].value and sigma == pytest.approx(res.sigma[name], rel=1e-15)
        assert unit == res.state[name].unit
    assert v.element_names == res.solve_for
    np.testing.assert_array_equal(v.covariance, res.P_consider)
    p = v.provenance
    assert p["config_hash"] == first.config.digest()
    assert p["mission"] == "sunpoint-nominal" and p["note"] == "check"
    assert (p["data_t0"], p["data_t1"]) == (0.0, 7200.0)
    assert p["models"] == {
        "TAM1": "magnetometer",
        "IRU": "gyro",
        "FHST1": "star_tracker",
        "FHST2": "star_tracker",
        "FSS1": "fine_sun",
        "CSS1": "coarse_sun",
    }
    assert p["physics"] == first.config.physics.as_dict()
    assert p["created_utc"].endswith("Z") and p["gcs_version"]


def test_saving_before_a_fit_is_refused(example_dir, tmp_path):
    unfitted = Analysis(AnalysisConfig(mission=example_dir).with_changes(diagnosis={"holdout_fraction": 0.0}))
    with pytest.raises(EstimationError, match="fit"):
        save_calibration(unfitted, tmp_path / "scds.h5")
    assert not (tmp_path / "scds.h5").exists()


def test_ground_attitude_goes_to_the_asf_with_its_sigma(fitted, tmp_path):
    first, _ = fitted
    path = tmp_path / "asf.h5"
    assert save_ground_attitude(first, path, note="frames") == 1
    sol = asf.read_solution(path, 1)
    assert sol.source == "batch" and sol.t.size == 7201  # TAM1's frames, 1 Hz
    np.testing.assert_allclose(np.linalg.norm(sol.q, axis=1), 1.0, atol=1e-12)
    assert np.all(np.isfinite(sol.sigma_rad)) and np.all(sol.sigma_rad > 0)
    one_arcsecond = np.radians(1 / 3600)
    assert np.all(sol.sigma_rad < 10 * one_arcsecond)  # two trackers, two hours
    # at the start the body axes are the roll/pitch/yaw axes (angles ≈ 0) and the gyro has
    # not yet carried the attitude: the fit's own att.* sigmas (1 s after t_ref)
    att_sigma = [first.result.sigma[n] for n in ("att.roll", "att.pitch", "att.yaw")]
    np.testing.assert_allclose(sol.sigma_rad[0], att_sigma, rtol=0.01)
    assert save_ground_attitude(first, path, step=60.0, scds_version=1) == 2
    grid = asf.read_solution(path, 2)
    np.testing.assert_allclose(np.diff(grid.t), 60.0)
    assert grid.provenance["scds_version"] == 1
    np.testing.assert_array_equal(asf.read_solution(path, 1).q, sol.q)  # solution 1 untouched
