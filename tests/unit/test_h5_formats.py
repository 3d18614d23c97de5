"""SDF, SCDS and ASF: round trips, and every damaged or busy file reported in one line."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest
from repo_paths import ROOT

from gcs_core.errors import DataFileError
from gcs_core.io import asf, h5store, locks, scds
from gcs_core.io.importer import load_mission
from gcs_core.io.sdf import iter_blocks, read_sdf
from gcs_core.io.sdf_write import write_sdf

one_nT = 1.0


@pytest.fixture(scope="module")
def imported(example_dir):
    return load_mission(example_dir)


def params(k: int = 0) -> dict:
    return {
        "TAM1.bias_x": (3.0 + k, 0.4, "nT"),
        "TAM1.bias_y": (-1.0, 0.4, "nT"),
        "IRU.bias_z": (1e-6 * k, 1e-7, "rad/s"),
    }


def append(path, k: int = 0, note: str = "") -> int:
    names = ["TAM1.bias_x", "TAM1.bias_y", "IRU.bias_z"]
    cov = np.diag([0.16, 0.16, 1e-14])
    return scds.append_version(
        path,
        sensor_params=params(k),
        covariance=cov,
        element_names=names,
        provenance={
            "data_t0": 0.0,
            "data_t1": 7200.0,
            "note": note,
            "models": ["magnetometer", "gyro"],
            "config_hash": "abc123",
        },
    )


def one_line_error(fn, *args, **kw) -> str:
    with pytest.raises(DataFileError) as info:
        fn(*args, **kw)
    message = str(info.value)
    assert "\n" not in message and "Traceback" not in message
    return message


# --- round trips ------------------------------------------------------------------------


def test_sdf_round_trip(tmp_path, imported):
    path = write_sdf(tmp_path / "m.sdf.h5", imported, block_seconds=600)
    sdf = read_sdf(path)
    assert sdf.file_type == 1 and not sdf.headers_only
    assert sdf.mission == "sunpoint-nominal" and sdf.epoch == imported.spec.epoch
    assert sdf.attitude_mode == "sun_pointing" and sdf.n_blocks == int(sdf.attrs["n_blocks"])
    assert {b.kind for b in sdf.blocks} == {"observation", "transition"}
    assert all(("IRU" in b.sensors) == (b.kind == "transition") for b in sdf.blocks)
    for name, table in imported.telemetry.items():
        parts = [b.sensors[name] for b in sdf.blocks if name in b.sensors]
        np.testing.assert_array_equal(np.concatenate([p.t for p in parts]), table.t)
        cols = parts[0].columns
        np.testing.assert_array_equal(np.concatenate([p.data for p in parts]), table.stack(cols))
        for p, b in zip(parts, (b for b in sdf.blocks if name in b.sensors)):
            np.testing.assert_array_equal(b.frame_t[p.frame], p.t)
            assert b.t0 <= p.t.min() and p.t.max() < b.t1
    tam = sdf.sensors["TAM1"]
    assert tam.type == "magnetometer" and tam.noise == 25.0 and tam.book["bias"] == [0, 0, 0]
    assert sdf.frames_n_points.shape == (sdf.frames_t.size, len(imported.telemetry))
    assert int(sdf.frames_n_points.sum()) == sum(len(t) for t in imported.telemetry.values())
    np.testing.assert_array_equal(sdf.ephemeris["r_I_km"], imported.ephemeris_table.stack(("rx", "ry", "rz")))
    np.testing.assert_array_equal(sdf.onboard["q"], imported.onboard.stack(("q1", "q2", "q3", "q4")))
    # the aux channels are held at each sample time (ICD §6)
    first = sdf.blocks[0].sensors["TAM1"]
    k = first.aux_columns.index("tam_temp")
    assert first.aux[0, k] == imported.aux.columns["tam_temp"][0]
    streamed = list(iter_blocks(path))
    assert [b.index for b in streamed] == [b.index for b in sdf.blocks]
    np.testing.assert_array_equal(streamed[3].frame_t, sdf.blocks[3].frame_t)


def test_sdf_headers_only(tmp_path, imported):
    path = write_sdf(tmp_path / "h.sdf.h5", imported, headers_only=True)
    sdf = read_sdf(path)
    assert sdf.file_type == 2 and sdf.headers_only
    assert all(s.data is None for b in sdf.blocks for s in b.sensors.values())
    total = sum(s.t.size for b in sdf.blocks for s in b.sensors.values())
    assert total == sum(len(t) for t in imported.telemetry.values())
    assert os.path.getsize(path) < os.path.getsize(write_sdf(tmp_path / "f.h5", imported))


def test_sdf_with_an_empty_aux_table_and_late_aux_rows(tmp_path, imported):
    from dataclasses import replace

    aux = imported.aux
    late = replace(aux, t=aux.t[100:], columns={k: v[100:] for k, v in aux.columns.items()}, lines=aux.lines[100:])
    sdf = read_sdf(write_sdf(tmp_path / "late.h5", replace(imported, aux=late)))
    held = sdf.blocks[0].sensors["TAM1"].aux
    assert np.all(np.isnan(held[:100])) and not np.any(np.isnan(held[100:]))
    empty = replace(aux, t=aux.t[:0], columns={k: v[:0] for k, v in aux.columns.items()}, lines=aux.lines[:0])
    sdf = read_sdf(write_sdf(tmp_path / "empty.h5", replace(imported, aux=empty)))
    assert np.all(np.isnan(sdf.blocks[0].sensors["TAM1"].aux))


def test_scds_round_trip_and_diff(tmp_path):
    path = tmp_path / "cal.scds.h5"
    assert [append(path, k, note=f"run {k}") for k in range(3)] == [1, 2, 3]
    versions = scds.list_versions(path)
    assert [v.version for v in versions] == [1, 2, 3]
    assert versions[1].note == "run 1" and versions[1].config_hash == "abc123"
    v2 = scds.read_version(path, 2)
    assert v2.params["TAM1.bias_x"] == (4.0, 0.4, "nT")
    assert v2.element_names == ("TAM1.bias_x", "TAM1.bias_y", "IRU.bias_z")
    np.testing.assert_array_equal(v2.covariance, np.diag([0.16, 0.16, 1e-14]))
    assert v2.provenance["models"] == ["magnetometer", "gyro"] and "created_utc" in v2.provenance
    assert scds.read_version(path).version == 3
    diff = {row[0]: row[1:] for row in scds.diff_versions(path, 1, 3)}
    value_a, value_b, delta, z = diff["TAM1.bias_x"]
    assert (value_a, value_b) == (3.0, 5.0) and abs(delta - 2.0) < 1e-12 * one_nT
    assert abs(z - 2.0 / np.hypot(0.4, 0.4)) < 1e-12
    assert diff["TAM1.bias_y"][3] == 0.0
    assert "has no calibration version 9" in one_line_error(scds.read_version, path, 9)


def test_asf_round_trip(tmp_path):
    path = tmp_path / "att.asf.h5"
    rng = np.random.default_rng(3)
    q = rng.normal(size=(50, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    t = np.arange(50.0) * 10
    sigma = np.full((50, 3), 1e-4)
    assert (
        asf.append_solution(
            path, t=t, q=q, sigma=sigma, source="batch", provenance={"scds_version": 2, "note": "first"}
        )
        == 1
    )
    assert asf.append_solution(path, t=t[:5], q=q[:5], sigma=sigma[:5], source="onboard") == 2
    sol = asf.read_solution(path, 1)
    np.testing.assert_array_equal(sol.q, q)
    np.testing.assert_array_equal(sol.t, t)
    assert sol.source == "batch" and sol.provenance["scds_version"] == 2
    assert [s.n for s in asf.list_solutions(path)] == [50, 5]
    with pytest.raises(ValueError):
        asf.append_solution(path, t=t, q=q * 2, sigma=sigma, source="batch")


# --- damaged files --------------------------------------------------------------------------


def test_truncated_file(tmp_path):
    path = tmp_path / "cal.scds.h5"
    append(path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    message = one_line_error(scds.list_versions, path)
    assert message == f"{path}: is truncated ({len(data) // 2} of {len(data)} bytes)"


@pytest.mark.parametrize("content,needle", [(b"t,bx\n0,1\n", "not an HDF5 file"), (b"", "empty")])
def test_not_hdf5(tmp_path, content, needle):
    path = tmp_path / "cal.scds.h5"
    path.write_bytes(content)
    assert needle in one_line_error(scds.read_version, path)
    assert needle in one_line_error(append, path)


def test_missing_and_wrong_format(tmp_path):
    assert "not found" in one_line_error(scds.list_versions, tmp_path / "nothing.h5")
    path = tmp_path / "att.asf.h5"
    asf.append_solution(path, t=[0.0], q=[[0, 0, 0, 1.0]], sigma=[[0, 0, 0.0]], source="x")
    assert "is a GCS ASF file, not SCDS" in one_line_error(scds.list_versions, path)
    plain = tmp_path / "plain.h5"
    with h5py.File(plain, "w") as f:
        f["x"] = 1
    assert "not a GCS SCDS file" in one_line_error(scds.list_versions, plain)
    with pytest.raises(DataFileError, match="no 'gcs_format' attribute"):
        with h5store.open_read(plain, "SCDS", max_version=1, check=False):
            pass


def test_flipped_byte_in_a_checksummed_chunk(tmp_path):
    path = tmp_path / "cal.scds.h5"
    append(path, 0)
    append(path, 1)
    with h5py.File(path, "r", locking=False) as f:
        info = f["versions/00001/value"].id.get_chunk_info(0)
    data = bytearray(path.read_bytes())
    data[info.byte_offset + 3] ^= 0x40
    path.write_bytes(bytes(data))
    # first line of defence: the whole-file SHA-256 of the GCS header block
    message = one_line_error(scds.read_version, path, 1)
    assert message == f"{path}: fails its checksum (SHA-256 of the whole file): the file is damaged"
    assert "checksum" in one_line_error(scds.list_versions, path)
    # second: the chunk's fletcher32, when the file is opened for salvage regardless
    with h5store.open_read(path, "SCDS", max_version=1, check=False) as f:
        assert f["versions/00002/value"][0] == 4.0  # an undamaged chunk still reads
    with pytest.raises(DataFileError) as info:
        with h5store.open_read(path, "SCDS", max_version=1, check=False) as f:
            f["versions/00001/value"][()]
    assert "fails its checksum" in str(info.value) and "\n" not in str(info.value)
    before = path.read_bytes()
    message = one_line_error(append, path, 2)
    assert "refusing to append" in message
    assert path.read_bytes() == before  # the damaged file is never rewritten
    assert "checksum" in one_line_error(h5store.verify, path, "SCDS", max_version=1)


def test_random_damage_is_always_reported(tmp_path):
    """HDF5 can hang on damaged metadata: the header checksum keeps it from ever seeing it."""
    path = tmp_path / "cal.scds.h5"
    for k in range(3):
        append(path, k)
    good = path.read_bytes()
    rng = np.random.default_rng(11)
    for _ in range(200):
        data = bytearray(good)
        for pos in rng.integers(0, len(data), size=rng.integers(1, 4)):
            data[pos] = (data[pos] + int(rng.integers(1, 256))) % 256
        path.write_bytes(bytes(data))
        message = one_line_error(scds.list_versions, path)
        assert "checksum" in message or "header" in message or "HDF5" in message


def test_lock_held_by_another_process(tmp_path, monkeypatch):
    path = tmp_path / "cal.scds.h5"
    append(path)
    holder = textwrap.dedent(f"""
        import sys, time
        from gcs_core.io import h5store
        with h5store.locked({str(path)!r}, exclusive=True):
            print("locked", flush=True)
            time.sleep(60)
    """)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-c", holder], stdout=subprocess.PIPE, env=env, text=True)
    try:
        assert proc.stdout.readline().strip() == "locked"
        monkeypatch.setattr(locks, "LOCK_WAIT_S", 0.1)
        message = one_line_error(append, path, 1)
        assert message == f"{path}: is in use by another GCS process (pid {proc.pid})"
        assert f"pid {proc.pid}" in one_line_error(scds.list_versions, path)
    finally:
        proc.kill()
        proc.wait()
    assert append(path, 1) == 2  # the kernel released the lock with the process


def test_locks_are_reentrant_and_shared_readers_coexist(tmp_path):
    path = tmp_path / "cal.scds.h5"
    append(path)
    with h5store.locked(path, exclusive=False):
        with h5store.locked(path, exclusive=False):
            assert len(scds.list_versions(path)) == 1
        assert append(path, 1) == 2  # upgrade within the same process
    assert not list(tmp_path.glob(".*.tmp"))
