"""Truth simulator: determinism, ICD format conformance, data gaps, gyro averaging, noise.

The model checks recompute the ICD §5 observation equations from the written files with
the lead's rotation helpers (an implementation independent of gcs_core.sim._rot) and the
simulator's truth attitude, and compare the residual spread with the configured noise.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from gcs_core import units
from gcs_core.frames import rotations as R
from gcs_core.sim.field import igrf_gci
from gcs_core.sim.scenarios import nominal_threeaxis
from gcs_core.sim.truth import World
from gcs_core.sim.writer import write_mission

one_nT = 1.0
one_arcsecond = units.ARCSEC


def aberrated(u, beta):
    """First-order aberration (Wertz 1978 §5.4): u' = unit(u + β − (u·β) u), β = v/c."""
    d = np.sum(u * beta, axis=-1, keepdims=True)
    w = u + beta - d * u
    return w / np.linalg.norm(w, axis=-1, keepdims=True)


def apparent_sun(world, t):
    """Sun seen from the moving spacecraft: parallax and orbital aberration (real physics)."""
    r, v = world.orbit(t)
    S = world.sun(t) - r
    return aberrated(S / np.linalg.norm(S, axis=1)[:, None], v / units.C_KM_S)


EXPECTED_HEADERS = {
    "magnetometer": "t,bx,by,bz",
    "gyro": "t,wx,wy,wz",
    "star_tracker": "t,h,v,ra,dec,mag",
    "fine_sun": "t,n_alpha,n_beta",
    "coarse_sun": "t,n_alpha,n_beta",
}


def _read(path: Path) -> tuple[list[str], np.ndarray]:
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    header = lines[0].split(",")
    data = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]]).reshape(-1, len(header))
    return header, data


@pytest.fixture(scope="module")
def mission(tmp_path_factory):
    root = tmp_path_factory.mktemp("sim")
    cfg = nominal_threeaxis("sun_pointing", seed=11, duration_s=7200.0)
    out = write_mission(cfg, root / "m", truth_path=root / "answers" / "m.json")
    return cfg, out, json.loads((root / "answers" / "m.json").read_text())


def test_same_seed_same_bytes_other_seed_other_noise(tmp_path):
    files = {}
    for tag, seed in (("a", 4), ("b", 4), ("c", 5)):
        cfg = nominal_threeaxis("inertial", seed=seed, duration_s=900.0)
        out = write_mission(cfg, tmp_path / tag)
        files[tag] = {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    assert files["a"] == files["b"]
    assert files["a"][Path("telemetry/TAM1.csv")] != files["c"][Path("telemetry/TAM1.csv")]
    assert files["a"][Path("ephemeris.csv")] == files["c"][Path("ephemeris.csv")]


def test_files_do_not_depend_on_the_chunking(tmp_path):
    """Week-long spans are written chunk by chunk; the chunk length must not change a byte."""
    blobs = []
    for chunk in (1800.0, 700.0):
        cfg = nominal_threeaxis("earth_pointing", seed=6, duration_s=1800.0)
        cfg.chunk_s = chunk
        out = write_mission(cfg, tmp_path / f"c{int(chunk)}")
        blobs.append({p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*.csv"))})
    assert blobs[0] == blobs[1]


def test_icd_directory_layout_and_headers(mission):
    cfg, out, truth = mission
    toml = tomllib.loads((out / "mission.toml").read_text())
    assert toml["mission"]["attitude_mode"] == "sun_pointing"
    assert toml["ephemeris"]["file"] == "ephemeris.csv"
    assert (out / toml["aux"]["file"]).exists() and (out / toml["onboard_attitude"]["file"]).exists()
    assert [s["name"] for s in toml["sensor"]] == [s.name for s in cfg.sensors]
    headers = {
        "ephemeris.csv": "t,rx,ry,rz,vx,vy,vz,sx,sy,sz",
        "aux.csv": "t,mtb_x,mtb_y,mtb_z,tam_temp",
        "onboard_attitude.csv": "t,q1,q2,q3,q4",
    }
    for s in toml["sensor"]:
        headers[s["telemetry"]] = EXPECTED_HEADERS[s["type"]]
        assert len(s["alignment_deg"]) == 3
    for rel, header in headers.items():
        cols, data = _read(out / rel)
        assert ",".join(cols) == header, rel
        assert data.shape[0] > 10, rel
        assert np.all(np.diff(data[:, 0]) > 0), f"{rel}: times not strictly increasing"
        assert np.all(np.isfinite(data)), rel
    _, eph = _read(out / "ephemeris.csv")
    assert eph[0, 0] == 0.0 and eph[-1, 0] == cfg.duration_s and np.max(np.diff(eph[:, 0])) <= 60.0
    _, q = _read(out / "onboard_attitude.csv")
    assert np.allclose(np.linalg.norm(q[:, 1:], axis=1), 1.0, atol=1e-11) and np.all(q[:, 4] >= 0)
    _, fss = _read(out / "telemetry/FSS1.csv")
    assert np.all(fss[:, 1:] == np.round(fss[:, 1:])), "Sun-sensor counts must be integers"
    assert truth["hidden_effects"] == [] and truth["sensors"]["TAM1"]["true"]["noise"] == 25.0
    assert not any(p.name.startswith(".") for p in out.parent.iterdir()), "temporary files left behind"


def test_eclipse_and_occultation_gaps(mission):
    cfg, out, truth = mission
    _, tam = _read(out / "telemetry/TAM1.csv")
    _, fss = _read(out / "telemetry/FSS1.csv")
    assert truth["sensors"]["FSS1"]["counters"]["n_eclipsed"] > 1000
    assert np.max(np.diff(fss[:, 0])) > 1200.0, "an eclipse (~35 min) must leave a gap"
    assert fss.shape[0] < tam.shape[0]
    world = World(cfg)
    r, _ = world.orbit(fss[:, 0])
    s = world.sun(fss[:, 0])
    # Every Sun-sensor sample is in sunlight: the spacecraft is outside the cylindrical umbra.
    behind = np.einsum("ij,ij->i", r, s) / np.linalg.norm(s, axis=1)
    perp = np.linalg.norm(r - behind[:, None] * s / np.linalg.norm(s, axis=1)[:, None], axis=1)
    assert np.all((behind > 0) | (perp > units.R_EARTH_KM))
    for name in ("FHST1", "FHST2"):
        assert truth["sensors"][name]["counters"]["n_occulted"] > 0
    _, st = _read(out / "telemetry/FHST2.csv")
    assert st.shape[0] < cfg.duration_s / 10.0


def test_ephemeris_rows_hermite_interpolate_to_the_truth(mission):
    """ICD §4: cubic Hermite between rows (with the velocities) must reproduce the orbit."""
    cfg, out, _ = mission
    _, e = _read(out / "ephemeris.csv")
    t0, t1 = e[:-1, 0], e[1:, 0]
    h = (t1 - t0)[:, None]
    p0, p1, v0, v1 = e[:-1, 1:4], e[1:, 1:4], e[:-1, 4:7], e[1:, 4:7]
    s = 0.5  # mid-interval
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    r_mid = h00 * p0 + h10 * h * v0 + h01 * p1 + h11 * h * v1
    r_true, _ = World(cfg).orbit(0.5 * (t0 + t1))
    assert np.max(np.linalg.norm(r_mid - r_true, axis=1)) < 1e-3  # 1 m
    sun_lin = 0.5 * (e[:-1, 7:10] + e[1:, 7:10])
    sun_true = World(cfg).sun(0.5 * (t0 + t1))
    ang = np.linalg.norm(np.cross(sun_lin, sun_true), axis=1) / np.linalg.norm(sun_true, axis=1) ** 2
    assert ang.max() < 1e-3 * one_arcsecond


def _truth_attitude(world, t):
    return world.attitude(np.asarray(t, dtype=float))


def test_gyro_rates_integrate_to_the_attitude_change(tmp_path):
    """Noise-free gyro rows (Eq 4-33 averages) integrate exactly to the true attitude."""
    cfg = nominal_threeaxis("earth_pointing", seed=2, duration_s=3600.0)
    cfg.sensors = [s for s in cfg.sensors if s.type == "gyro"]
    cfg.sensors[0].true.update(arw=0.0, rrw=0.0)
    out = write_mission(cfg, tmp_path / "g")
    _, y = _read(out / "telemetry/IRU.csv")
    world = World(cfg)
    C = _truth_attitude(world, [0.0])[0]
    for k in range(y.shape[0]):
        C = R.rotvec_to_dcm(y[k, 1:] * 1.0) @ C  # C(t_k) = exp(-[ω Δt x]) C(t_k-1)
    C_true = _truth_attitude(world, [y[-1, 0]])[0]
    err = np.linalg.norm(R.dcm_to_rotvec(C @ C_true.T))
    assert err < 1e-3 * one_arcsecond


def test_gyro_noise_matches_arw_and_rrw(mission):
    cfg, out, truth = mission
    world = World(cfg)
    _, y = _read(out / "telemetry/IRU.csv")
    t = y[:, 0]
    res = y[:, 1:] - world.omega_avg(t - 1.0, t)
    arw, rrw = 3.162278e-07, 3.162278e-10
    expected = math.sqrt(arw**2 + rrw**2 / 12.0)  # Farrenkopf, Δt = 1 s
    # First differences remove the slowly wandering bias (its step adds σ_u² Δt, negligible).
    d = np.diff(res, axis=0) / math.sqrt(2.0)
    assert np.std(d) == pytest.approx(expected, rel=0.03)
    # The bias wanders as a random walk from the data-book value 0: |b(T)| ~ σ_u sqrt(T).
    bias_end = np.asarray(truth["gyro_bias_history"]["IRU"][-1][1:])
    assert np.all(np.abs(bias_end) < 5 * rrw * math.sqrt(cfg.duration_s))
    assert np.abs(res[-600:].mean(axis=0) - bias_end).max() < 5 * arw / math.sqrt(600) + 1e-9


def test_gyro_integration_error_is_angle_random_walk(tmp_path):
    """With σ_u = 0 the integrated angle error over T is N(0, σ_v² T) per axis."""
    cfg = nominal_threeaxis("sun_pointing", seed=8, duration_s=3600.0)
    cfg.sensors = [s for s in cfg.sensors if s.type == "gyro"]
    cfg.sensors[0].true.update(rrw=0.0)
    out = write_mission(cfg, tmp_path / "g")
    _, y = _read(out / "telemetry/IRU.csv")
    world = World(cfg)
    T, arw, errs = 300, 3.162278e-07, []
    for k0 in range(0, y.shape[0] - T + 1, T):
        C = world.attitude(np.array([y[k0, 0] - 1.0]))[0]
        for k in range(k0, k0 + T):
            C = R.rotvec_to_dcm(y[k, 1:]) @ C
        errs.append(R.dcm_to_rotvec(C @ world.attitude(np.array([y[k0 + T - 1, 0]]))[0].T))
    z = np.asarray(errs) / (arw * math.sqrt(T))
    assert z.size == 36
    assert 0.62 < np.sqrt(np.mean(z**2)) < 1.42  # chi-square, 36 dof, 99.9 %


def test_magnetometer_residual_is_the_configured_noise(mission):
    cfg, out, _ = mission
    world = World(cfg)
    _, b = _read(out / "telemetry/TAM1.csv")
    t = b[:, 0]
    r, _ = world.orbit(t)
    B_I = igrf_gci(world.epoch, world.jd0, t, r)
    B_S = np.einsum("nij,nj->ni", world.attitude(t), B_I)  # M = I, bias 0 in the book
    res = b[:, 1:] - B_S
    assert np.abs(res.mean(axis=0)).max() < 2.0 * one_nT
    assert res.std() == pytest.approx(25.0, rel=0.03)


def test_star_tracker_follows_icd_model_within_noise(mission):
    cfg, out, _ = mission
    world = World(cfg)
    for name in ("FHST1", "FHST2"):
        s = cfg.sensor(name)
        M = R.euler123_to_dcm(*np.radians(s.book["alignment_deg"]))
        _, d = _read(out / f"telemetry/{name}.csv")
        ra, dec = np.radians(d[:, 3]), np.radians(d[:, 4])
        F_I = np.stack([np.cos(ra) * np.cos(dec), np.sin(ra) * np.cos(dec), np.sin(dec)], -1)
        _, v_sc = world.orbit(d[:, 0])
        v_earth = -(world.sun(d[:, 0] + 1.0) - world.sun(d[:, 0] - 1.0)) / 2.0  # Earth about the Sun
        F_I = aberrated(F_I, (v_earth + v_sc) / units.C_KM_S)  # stellar aberration
        F_S = np.einsum("ij,njk,nk->ni", M, world.attitude(d[:, 0]), F_I)
        h = np.arcsin(F_S[:, 2])  # Eq 4-29, S_H = S_V = 1
        v = np.arctan2(F_S[:, 1], F_S[:, 0])
        res = np.concatenate([d[:, 1] - h, d[:, 2] - v])
        assert np.all(np.abs(d[:, 1:3]) < np.radians(4.0) + 10 * s.book["noise"])
        assert res.std() / s.book["noise"] == pytest.approx(1.0, abs=0.08)
        assert np.abs(res.mean()) < 0.5 * one_arcsecond * 8 / math.sqrt(len(res) / 100)


@pytest.mark.parametrize("name", ["FSS1", "CSS1"])
def test_sun_sensor_counts_follow_icd_model_within_noise(mission, name):
    cfg, out, _ = mission
    world = World(cfg)
    s = cfg.sensor(name)
    _, d = _read(out / f"telemetry/{name}.csv")
    t = d[:, 0]
    S_I = apparent_sun(world, t)
    M = R.euler123_to_dcm(*np.radians(s.book["alignment_deg"]))
    S_S = np.einsum("ij,njk,nk->ni", M, world.attitude(t), S_I)
    if s.type == "fine_sun":
        A1, A2, A3, k = s.book["coeff_alpha"]
        ta, tb = S_S[:, 1] / S_S[:, 0], S_S[:, 2] / S_S[:, 0]
        pred = np.stack([(ta - A1 - A3 * np.sin(k * ta)) / A2, (tb - A1 - A3 * np.sin(k * tb)) / A2], -1)
    else:
        K = s.book["scale"][0]
        pred = np.stack([np.arctan2(S_S[:, 1], S_S[:, 0]), np.arctan2(S_S[:, 2], S_S[:, 0])], -1) / K
    res = d[:, 1:] - pred
    assert res.std() / s.book["noise"] == pytest.approx(1.0, abs=0.04)
    assert np.abs(res.mean(axis=0)).max() < 0.05


def test_onboard_attitude_carries_the_injected_error(mission):
    cfg, out, truth = mission
    world = World(cfg)
    _, q = _read(out / "onboard_attitude.csv")
    C_ob = R.quat_to_dcm(q[:, 1:])
    err = R.dcm_to_rotvec(C_ob @ np.swapaxes(world.attitude(q[:, 0]), 1, 2))
    expected = np.radians(truth["onboard_attitude"]["error_deg"])
    assert np.allclose(err.mean(axis=0), expected, atol=0.5 * one_arcsecond)
    assert err.std(axis=0) == pytest.approx(np.full(3, 2.0 * one_arcsecond), rel=0.15)


def test_bad_configuration_is_one_clear_line(tmp_path):
    from gcs_core.errors import InputError

    cfg = nominal_threeaxis("sun_pointing", seed=1, duration_s=60.0)
    cfg.attitude_mode = "tumbling"
    with pytest.raises(InputError, match="attitude_mode"):
        write_mission(cfg, tmp_path / "x")
    assert not (tmp_path / "x").exists()


def test_gyro_read_out_noise_telescopes(tmp_path):
    """The electronic (read-out) noise σ_e is an error of the integrated angle at each
    sample (ICD §5 ``electronic``): a rate row carries ``(e_k − e_{k−1})/Δt``, so its
    spread is sqrt(2) σ_e/Δt with lag-one correlation −1/2, and the integrated angle error
    over any span is the difference of two read-outs, sqrt(2) σ_e, not growing with it."""
    cfg = nominal_threeaxis("sun_pointing", seed=9, duration_s=1800.0)
    cfg.sensors = [s for s in cfg.sensors if s.type == "gyro"]
    sig_e = 2e-5
    cfg.sensors[0].true.update(arw=0.0, rrw=0.0, electronic=sig_e)
    out = write_mission(cfg, tmp_path / "g")
    _, y = _read(out / "telemetry/IRU.csv")
    t = y[:, 0]
    res = y[:, 1:] - World(cfg).omega_avg(t - 1.0, t)  # Δt = 1 s
    n = res.shape[0]
    assert np.std(res) == pytest.approx(math.sqrt(2.0) * sig_e, rel=4 / math.sqrt(3 * n))
    lag1 = np.mean(res[1:] * res[:-1]) / np.mean(res * res)
    assert lag1 == pytest.approx(-0.5, abs=4 / math.sqrt(3 * n))
    S = np.cumsum(res, axis=0)  # integrated angle error
    for T in (10, 900):
        ang = S[T:] - S[:-T]  # e_{k+T} − e_k
        assert np.std(ang) == pytest.approx(math.sqrt(2.0) * sig_e, rel=4 / math.sqrt(3 * (n - T))), T
