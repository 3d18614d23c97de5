"""CCSDS at the boundary (gcs_core.fleet.ccsds, through the ccsds-ndm library): an exported
AEM reads back within 1e-12; a mission whose ephemeris is an OEM fits identically to the
same ephemeris as CSV; an OEM GCS cannot take is one line naming the file."""

from __future__ import annotations

import shutil
from datetime import UTC, datetime

import numpy as np
import pytest

pytest.importorskip("ccsds_ndm")

from gcs_core.config_schema import AnalysisConfig
from gcs_core.errors import InputError
from gcs_core.fleet.ccsds import read_aem, write_aem
from gcs_core.io.ccsds import read_oem_table, utc_text
from gcs_core.io.importer import load_mission
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import nominal_threeaxis
from gcs_core.sim.writer import write_mission

#: the round trip's tolerance on a quaternion component and on a time [s]
ROUND_TRIP = 1e-12
EPOCH = datetime(2024, 5, 14, 4, 0, 0, tzinfo=UTC)


def test_an_exported_aem_reads_back_through_the_library_within_1e_12(tmp_path):
    rng = np.random.default_rng(2025)
    n = 200
    t = np.sort(rng.uniform(0.0, 86400.0, n))
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 3] < 0] *= -1
    path = write_aem(tmp_path / "sc.aem.xml", t, q, EPOCH, object_name="SC01", comments=("test",))
    t2, q2 = read_aem(path, EPOCH)
    assert np.max(np.abs(q2 - q)) <= ROUND_TRIP
    assert np.max(np.abs(t2 - t)) <= ROUND_TRIP
    text = path.read_text()
    assert "<REF_FRAME_A>EME2000</REF_FRAME_A>" in text and "<TIME_SYSTEM>UTC</TIME_SYSTEM>" in text


def _oem(eph, epoch, frame="EME2000") -> str:
    head = [
        "CCSDS_OEM_VERS = 2.0",
        "CREATION_DATE = 2024-05-14T00:00:00",
        "ORIGINATOR = GCS-TEST",
        "",
        "META_START",
        "OBJECT_NAME = SC01",
        "OBJECT_ID = 2024-001A",
        "CENTER_NAME = EARTH",
        f"REF_FRAME = {frame}",
        "TIME_SYSTEM = UTC",
        f"START_TIME = {utc_text(epoch, eph.t[0])}",
        f"STOP_TIME = {utc_text(epoch, eph.t[-1])}",
        "META_STOP",
        "",
    ]
    cols = ("rx", "ry", "rz", "vx", "vy", "vz")
    rows = [
        utc_text(epoch, eph.t[i]) + " " + " ".join(repr(float(eph.columns[c][i])) for c in cols)
        for i in range(len(eph))
    ]
    return "\n".join(head + rows) + "\n"


@pytest.fixture(scope="module")
def missions(tmp_path_factory):
    """The same simulated mission twice: its ephemeris as an OEM, and as the ICD CSV with the
    same numbers (the OEM has no Sun: both carry the Sun GCS computes for an OEM)."""
    root = tmp_path_factory.mktemp("oem")
    src = write_mission(nominal_threeaxis("sun_pointing", seed=11, duration_s=900.0, name="oem-test"), root / "src")
    eph = load_mission(src).ephemeris_table
    spec_epoch = load_mission(src).spec.epoch
    oem_dir, csv_dir = root / "oem", root / "csv"
    shutil.copytree(src, oem_dir)
    (oem_dir / "orbit.oem").write_text(_oem(eph, spec_epoch))
    (oem_dir / "ephemeris.csv").unlink()
    toml = oem_dir / "mission.toml"
    toml.write_text(toml.read_text().replace('file = "ephemeris.csv"', 'file = "orbit.oem"'))
    table = read_oem_table(oem_dir / "orbit.oem", spec_epoch)
    shutil.copytree(src, csv_dir)
    names = ("t", "rx", "ry", "rz", "vx", "vy", "vz", "sx", "sy", "sz")
    lines = [",".join(names)] + [",".join(repr(float(table.columns[c][i])) for c in names) for i in range(len(table))]
    (csv_dir / "ephemeris.csv").write_text("\n".join(lines) + "\n")
    return oem_dir, csv_dir


def test_a_mission_whose_ephemeris_is_an_oem_fits_identically_to_the_csv(missions):
    oem_dir, csv_dir = missions
    a_oem = Analysis(AnalysisConfig(mission=oem_dir, method="batch").with_changes(diagnosis={"holdout_fraction": 0.0}))
    a_csv = Analysis(AnalysisConfig(mission=csv_dir, method="batch").with_changes(diagnosis={"holdout_fraction": 0.0}))
    for name in ("t", "rx", "ry", "rz", "vx", "vy", "vz", "sx", "sy", "sz"):
        np.testing.assert_array_equal(
            a_oem.mission.ephemeris_table.columns[name], a_csv.mission.ephemeris_table.columns[name]
        )
    r_oem, r_csv = a_oem.fit(holdout=False), a_csv.fit(holdout=False)
    assert r_oem.status == r_csv.status == "converged"
    assert r_oem.state.values() == r_csv.state.values()  # bit for bit
    assert r_oem.chi2 == r_csv.chi2
    assert a_oem.mission.report.file("ephemeris (CCSDS OEM)").rows == len(a_csv.mission.ephemeris_table)


@pytest.mark.parametrize(
    "edit, words",
    [
        (lambda t: t.replace("REF_FRAME = EME2000", "REF_FRAME = ITRF"), "REF_FRAME = ITRF"),
        (lambda t: t.replace("TIME_SYSTEM = UTC", "TIME_SYSTEM = TAI"), "TIME_SYSTEM = TAI"),
        (lambda t: t.replace("CENTER_NAME = EARTH", "CENTER_NAME = MOON"), "CENTER_NAME = MOON"),
        (lambda t: t.replace("META_STOP", "META_STP"), "holds no state vector"),
        (lambda t: t.replace("CCSDS_OEM_VERS = 2.0", "CCSDS_OEM_VERS = 9.9"), "not a readable CCSDS OEM"),
    ],
)
def test_an_oem_gcs_cannot_take_is_one_line_naming_the_file(missions, tmp_path, edit, words):
    oem_dir, _ = missions
    bad = tmp_path / "m"
    shutil.copytree(oem_dir, bad)
    f = bad / "orbit.oem"
    f.write_text(edit(f.read_text()))
    with pytest.raises(InputError) as err:
        load_mission(bad)
    msg = str(err.value)
    assert words in msg and str(f) in msg and "\n" not in msg
