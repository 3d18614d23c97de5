"""The BROAD converter on a tiny trial written in the test, a malformed file, and the
ground mission it gives (``gcs import`` accepts it).

The tiny trial imitates the layout of BROAD (Laidig et al., Data 6(7), 2021,
doi:10.3390/data6070072): datasets ``imu_gyr`` [rad/s], ``imu_acc`` [m/s²], ``imu_mag``
[µT], ``opt_quat`` (w, x, y, z; NaN while untracked), ``opt_pos`` [m], ``movement`` and the
attribute ``sampling_rate`` [Hz]. Its numbers are simulated (seeded), not BROAD's.
"""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from gcs_core.convert import CONVERTERS, ConversionReport, convert
from gcs_core.convert.broad import LAB_LATITUDE_DEG
from gcs_core.errors import InputError
from gcs_core.frames.rotations import quat_from_dcm, quat_to_dcm, rotvec_to_dcm
from gcs_core.io.importer import load_mission
from gcs_core.units import OMEGA_EARTH

RATE_HZ = 100.0
N = 1200
GYRO_NOISE = 2e-3  # rad/s per sample
MAG_NOISE_UT = 0.5  # µT per sample
OPT_NOISE = 1e-4  # rad per axis
one_percent = 0.01


#: BROAD's magnetometer on the bus, one period: N a new sample, m the mean of its
#: neighbours, h the sample before read again (docs of gcs_core.convert.holds)
BUS_PATTERN = "NmNhhm"


def _bus(y):
    """The magnetometer as BROAD's bus delivers it (:data:`BUS_PATTERN`): held repeats and
    interpolated midpoints; returns the samples and the pattern letter of each."""
    out = np.array(y, dtype=float)
    kind = np.array([BUS_PATTERN[k % len(BUS_PATTERN)] for k in range(len(out))])
    for k in range(1, len(out)):
        if kind[k] == "h":
            out[k] = out[k - 1]
    for k in range(1, len(out) - 1):
        if kind[k] == "m":
            out[k] = 0.5 * (out[k - 1] + out[k + 1])
    if kind[-1] == "m":
        kind[-1] = "N"
    return out, kind


def _trial(path, *, drop=None, rate=RATE_HZ, bad_quat=False, bus=False, gyro_step=None):
    rng = np.random.default_rng(7)
    t = np.arange(N) / rate
    moving = t > 6.0
    omega = np.where(moving[:, None], np.column_stack([0.5 * np.sin(t), 0.3 * np.cos(0.7 * t), 0.2 + 0 * t]), 0.0)
    C = np.empty((N, 3, 3))
    C[0] = np.eye(3)
    for k in range(1, N):
        C[k] = rotvec_to_dcm(omega[k] / rate) @ C[k - 1]
    q_xyzw = quat_from_dcm(rotvec_to_dcm(rng.normal(scale=OPT_NOISE, size=(N, 3))) @ C)
    q = np.column_stack([q_xyzw[:, 3], q_xyzw[:, :3]])
    q[:15] = np.nan  # untracked start
    if bad_quat:
        q[100] *= 2.0
    B_enu = np.array([0.5, 17.0, -45.0])
    mag = np.einsum("nij,j->ni", C, B_enu) + rng.normal(scale=MAG_NOISE_UT, size=(N, 3))
    if bus:
        mag = _bus(mag)[0]
    gyr = omega + 0.003 + rng.normal(scale=GYRO_NOISE, size=(N, 3))
    if gyro_step:  # quantized: exact repeats at rest by chance
        gyr = np.round(gyr / gyro_step) * gyro_step
    pos = np.array([0.1, -0.4, 1.5]) + 0.2 * rng.normal(size=(N, 3))
    pos[:15] = np.nan  # untracked start
    data = {
        "imu_gyr": gyr,
        "imu_acc": rng.normal(size=(N, 3)),
        "imu_mag": mag,
        "opt_quat": q,
        "opt_pos": pos,
        "movement": moving,
    }
    with h5py.File(path, "w") as f:
        for k, v in data.items():
            if k != drop:
                f[k] = v
        f.attrs["sampling_rate"] = rate
        f.attrs["info"] = "a simulated trial in BROAD's layout"
    return path


def test_registered():
    assert CONVERTERS["broad"] == "gcs_core.convert.broad"


def test_converts_to_a_mission_that_imports(tmp_path):
    src = _trial(tmp_path / "trial.hdf5")
    (tmp_path / "LICENSE").write_text("CC BY 4.0\n")
    rep = convert("broad", src, tmp_path / "m")
    assert isinstance(rep, ConversionReport)
    assert rep.samples["telemetry/GYR.csv"] == rep.samples["telemetry/OPT.csv"] == N  # every sample
    assert any("untracked for its first 15 samples" in t for t in rep.notes)
    m = load_mission(tmp_path / "m")
    assert m.spec.ground_position_km is not None
    # the lab's latitude (Berlin) gives the Earth's rate in ENU: no East component
    lat = np.radians(LAB_LATITUDE_DEG)
    earth = OMEGA_EARTH * np.array([0.0, np.cos(lat), np.sin(lat)])
    assert m.spec.earth_rate_rad_s is not None and np.allclose(m.spec.earth_rate_rad_s, earth, rtol=0, atol=1e-15)
    assert [s.type for s in m.spec.sensors] == ["gyro", "magnetometer", "attitude_reference"]
    assert len(m.telemetry["OPT"]) == N - 15 and m.telemetry["OPT"].dropped_nan == 15
    # µT -> nT, and the noise written is the one the telemetry shows (white here)
    mag = m.spec.sensor("MAG")
    assert abs(mag.noise / (MAG_NOISE_UT * 1000.0) - 1.0) < 0.15
    assert abs(m.spec.sensor("OPT").noise / OPT_NOISE - 1.0) < 0.15
    assert np.allclose(m.telemetry["MAG"].columns["bx"][:3] / 1000.0, h5py.File(src)["imu_mag"][:3, 0], atol=1e-6)
    # the quaternion keeps its C_BI: reordered scalar-last, unchanged otherwise
    q_src = h5py.File(src)["opt_quat"][20]
    q_gcs = np.array([m.telemetry["OPT"].columns[c][5] for c in ("q1", "q2", "q3", "q4")])
    assert np.allclose(quat_to_dcm(q_gcs), quat_to_dcm(np.r_[q_src[1:], q_src[0]]), atol=1e-9)
    for f in ("SOURCE.md", "LICENSE", "conversion.json"):
        assert (tmp_path / "m" / f).is_file()
    assert "doi:10.3390/data6070072" in (tmp_path / "m" / "mission.toml").read_text()
    assert "ESTIMATED" in (tmp_path / "m" / "mission.toml").read_text()


def test_span_extract(tmp_path):
    rep = convert("broad", _trial(tmp_path / "t.hdf5"), tmp_path / "m", span=(1.0, 9.0))
    assert rep.samples["telemetry/MAG.csv"] == 801
    assert any("extract" in w for w in rep.notes)


def test_optical_position_becomes_the_gradient_lever(tmp_path):
    """The optical position is the aux channels pos_x/y/z [m, ENU] from the whole file's mean
    tracked position (the same point for any span), untracked samples left out."""
    src = _trial(tmp_path / "t.hdf5")
    pos = h5py.File(src)["opt_pos"][()]
    mean = np.nanmean(pos, axis=0)
    for out, span in ((tmp_path / "whole", None), (tmp_path / "part", (1.0, 9.0))):
        convert("broad", src, out, span=span)
        m = load_mission(out)
        aux = m.aux
        assert tuple(c for c in aux.columns if c != "t") == ("pos_x", "pos_y", "pos_z")
        t = np.asarray(aux.t)
        k = np.rint(t * RATE_HZ).astype(int)
        assert np.all(np.isfinite(pos[k]).all(axis=1))  # untracked rows left out
        assert len(t) == (N - 15 if span is None else 801)
        got = np.column_stack([aux.columns[c] for c in ("pos_x", "pos_y", "pos_z")])
        assert np.allclose(got, pos[k] - mean, atol=2e-6)  # written to 1 µm


@pytest.mark.parametrize(
    "kind, message",
    [
        ("missing", "dataset 'imu_mag'"),
        ("text", "not an HDF5 file"),
        ("quat", "not a unit quaternion at sample 100"),
    ],
)
def test_malformed_file_is_one_clear_error(tmp_path, kind, message):
    src = tmp_path / "t.hdf5"
    if kind == "missing":
        _trial(src, drop="imu_mag")
    elif kind == "text":
        src.write_text("t,wx\n0,1\n")
    else:
        _trial(src, bad_quat=True)
    with pytest.raises(InputError, match=message) as err:
        convert("broad", src, tmp_path / "m")
    assert "t.hdf5" in str(err.value)
    assert not (tmp_path / "m").exists()  # nothing half-written


def test_a_reference_without_noise_at_rest_gets_a_floor_and_a_warning(tmp_path, monkeypatch):
    import gcs_core.convert.broad as broad

    monkeypatch.setattr(broad.noise_mod, "white_level", lambda curve, dt: (0.0, dt, True))
    rep = convert("broad", _trial(tmp_path / "t.hdf5"), tmp_path / "m")
    assert any("no noise measurable at rest" in w for w in rep.notes)
    load_mission(tmp_path / "m")  # every noise written is > 0


def test_refuses_a_full_output_directory_unless_forced(tmp_path):
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "x").write_text("")
    src = _trial(tmp_path / "t.hdf5")
    with pytest.raises(InputError, match="not empty"):
        convert("broad", src, tmp_path / "m")
    with pytest.raises(InputError, match="not made by gcs convert"):  # issue 23: --force only on GCS's own
        convert("broad", src, tmp_path / "m", overwrite=True)
    assert (tmp_path / "m" / "x").exists()
    (tmp_path / "m" / "x").unlink()
    convert("broad", src, tmp_path / "m")
    (tmp_path / "m" / "x").write_text("")
    convert("broad", src, tmp_path / "m", overwrite=True)  # gcs convert --force on a converted directory
    assert not (tmp_path / "m" / "x").exists()
    assert (tmp_path / "m" / "mission.toml").is_file()


def test_an_option_of_another_format_is_refused(tmp_path):
    with pytest.raises(InputError, match="'tle' does not apply to the 'broad' converter"):
        convert("broad", _trial(tmp_path / "t.hdf5"), tmp_path / "m", tle="iss.tle")


def test_cli_convert_import_and_noise(tmp_path, capsys):
    from gcs_tui.cli.commands import (
        EXIT_INPUT,
        EXIT_OK,
        main,
    )

    src = _trial(tmp_path / "t.hdf5")
    assert main(["-q", "convert", "broad", str(src), "--out", str(tmp_path / "m")]) == EXIT_OK
    assert "telemetry/OPT.csv: 1200 samples" in capsys.readouterr().out
    assert main(["-q", "import", str(tmp_path / "m")]) == EXIT_OK
    capsys.readouterr()
    assert main(["-q", "noise", str(tmp_path / "m"), "--start", "0.5", "--end", "5.5"]) == EXIT_OK
    out = capsys.readouterr().out
    assert "ARW N =" in out and "Allan deviation [nT]" in out
    (tmp_path / "bad.hdf5").write_text("no")
    assert main(["-q", "convert", "broad", str(tmp_path / "bad.hdf5"), "--out", str(tmp_path / "n")]) == EXIT_INPUT
    err = capsys.readouterr().err
    assert "bad.hdf5" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_held_repeats_and_interpolated_samples_are_flagged_and_counted(tmp_path):
    """The magnetometer read by a faster bus (BROAD's pattern): each held repeat written
    with flag 2, each interpolated midpoint with flag 3, every sample kept, the import
    leaves them out, the report counts them with the run lengths; the noise written is
    that of the samples used. A gyro quantized coarser than its noise repeats by chance
    at rest: counted, not flagged."""
    step = 1.5 * GYRO_NOISE
    src = _trial(tmp_path / "t.hdf5", bus=True, gyro_step=step)
    rep = convert("broad", src, tmp_path / "m")
    _, kind = _bus(np.zeros((N, 3)))
    n_h, n_m = int((kind == "h").sum()), int((kind == "m").sum())
    text = (tmp_path / "m/telemetry/MAG.csv").read_text().splitlines()
    assert text[0].startswith("# flag 2 = held repeat") and text[1] == "t,bx,by,bz,flag"
    flags = np.array([int(ln.rsplit(",", 1)[1]) for ln in text[2:]])
    assert flags.size == N  # every sample kept
    assert np.array_equal(flags == 2, kind == "h") and np.array_equal(flags == 3, kind == "m")
    lines = [x for x in rep.notes if x.startswith("repeats: magnetometer")]
    assert any(f"{n_h} of {N} samples" in x and "flagged (flag = 2)" in x for x in lines)
    assert any(f"{n_m} of {N} samples" in x and "flagged (flag = 3)" in x for x in lines)
    assert any("1× 600, 3× 200" in x for x in lines)  # the run lengths per NmNhhm: 1, 1, 3, 1
    gyro = [x for x in rep.notes if x.startswith("repeats: gyro") and "repeat the sample" in x]
    assert gyro and "quantization, kept" in gyro[0] and not gyro[0].startswith("repeats: gyro: 0 of")
    assert (tmp_path / "m/telemetry/GYR.csv").read_text().startswith("t,wx,wy,wz\n")  # no flag column
    toml = (tmp_path / "m/mission.toml").read_text()
    assert f"{n_h} held repeats (flag = 2), {n_m} interpolated (flag = 3)" in toml
    assert "held repeat" in (tmp_path / "m/SOURCE.md").read_text()
    m = load_mission(tmp_path / "m")
    assert len(m.telemetry["MAG"]) == N - n_h - n_m
    # the samples used are white (σ 0.5 µT): the line per sample used is their σ
    assert abs(m.spec.sensor("MAG").noise / (MAG_NOISE_UT * 1000.0) - 1.0) < 0.15
