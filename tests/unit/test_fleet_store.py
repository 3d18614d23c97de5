"""The fleet store's index of what is done (gcs_core.fleet.store): it follows its own appends,
and any change of the file by anyone else makes it read the file again (no fit, no cluster)."""

from __future__ import annotations

import numpy as np

from gcs_core.fleet.store import FleetStore
from gcs_core.fleet.task import Outcome


def _outcome(day: str, digest: str) -> Outcome:
    n = 5
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    return Outcome(
        "SC01",
        day,
        digest,
        calibration={
            "sensor_params": {"TAM1.bias_x": (1.0, 0.1, "nT")},
            "covariance": np.array([[0.01]]),
            "element_names": ["TAM1.bias_x"],
            "provenance": {"data_t0": 0.0, "data_t1": 4.0, "note": day},
        },
        attitude={
            "t": np.arange(n, dtype=float),
            "q": q,
            "sigma": np.zeros((n, 3)),
            "source": "batch",
            "provenance": {},
        },
        summary={"status": "converged"},
    )


def test_the_index_follows_its_own_appends_and_rereads_a_file_changed_by_another(tmp_path):
    ours, theirs = FleetStore(tmp_path), FleetStore(tmp_path)
    assert ours.done("SC01", "h1").scds_version is None
    ours.append(_outcome("day1", "h1"))
    d = ours.done("SC01", "h1")
    assert (d.scds_version, d.asf_solution) == (1, 1)
    assert ours.calibrations("SC01") == FleetStore(tmp_path).calibrations("SC01")  # the index is the file

    theirs.append(_outcome("day2", "h2"))  # another process (its own store) appends
    d = ours.done("SC01", "h2")
    assert (d.scds_version, d.asf_solution) == (2, 2)
    ours.append(_outcome("day3", "h3"))
    assert [n for n, _ in ours.calibrations("SC01")] == [1, 2, 3]
    assert ours.attitudes("SC01") == FleetStore(tmp_path).attitudes("SC01")
