"""Hidden effects: each one changes the truth the way its definition says, and is recorded.

Base and effect runs share their random streams (seeded per sensor name), so the
difference of the two isolates the effect.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gcs_core import units
from gcs_core.errors import InputError
from gcs_core.frames import rotations as R
from gcs_core.sim.aux import AuxSchedule
from gcs_core.sim.scenarios import list_effects, nominal_threeaxis, spinner_nominal, with_effect
from gcs_core.sim.stars import StarCatalog
from gcs_core.sim.truth import World
from gcs_core.sim.writer import _rng, make_sensor_sim, write_mission

one_nT = 1.0
one_arcsecond = units.ARCSEC
D = 1800.0


def run(cfg, name, t, **true):
    """Telemetry columns of one sensor at times ``t`` (the writer's seeding)."""
    s = cfg.sensor(name)
    s.true.update(true)
    world = World(cfg)
    aux = AuxSchedule(cfg.aux, cfg.duration_s, _rng(cfg.seed, "aux")) if cfg.aux else None
    cat = StarCatalog(cfg.catalog_seed) if s.type == "star_tracker" else None
    sim = make_sensor_sim(s, world, _rng(cfg.seed, name), catalog=cat, aux=aux)
    return sim.run(np.asarray(t, dtype=float)), world, aux


@pytest.fixture()
def base():
    return nominal_threeaxis("sun_pointing", seed=21, duration_s=D)


T1HZ = np.arange(0.0, D + 1.0)
T10 = np.arange(0.0, D + 1.0, 10.0)


def test_tam_bias_contamination_and_time_offset(base):
    y0, _, aux = run(base, "TAM1", T1HZ)
    y1, _, _ = run(with_effect(base, "TAM1.bias", 200.0), "TAM1", T1HZ)
    diff = np.stack([y1[c] - y0[c] for c in ("bx", "by", "bz")], -1)
    assert np.allclose(diff, 200.0 * np.array([0.6, -0.48, 0.64]), atol=1e-6)
    y2, _, _ = run(with_effect(base, "TAM1.contamination_mtb_x", 0.5), "TAM1", T1HZ)
    diff = np.stack([y2[c] - y0[c] for c in ("bx", "by", "bz")], -1)
    k = 0.5 * np.array([0.8, -0.5, 0.33]) / np.linalg.norm([0.8, -0.5, 0.33])
    assert np.allclose(diff, aux.value("mtb_x", T1HZ)[:, None] * k, atol=1e-6)
    assert np.ptp(aux.value("mtb_x", T1HZ)) > 0, "the torquer must switch during the test span"
    y3, _, _ = run(with_effect(base, "TAM1.time_offset", 0.5), "TAM1", T1HZ)
    b0 = np.stack([y0[c] for c in ("bx", "by", "bz")], -1)
    rate = np.gradient(b0, T1HZ, axis=0)
    diff = np.stack([y3[c] - y0[c] for c in ("bx", "by", "bz")], -1)
    # the noise is shared, so the difference is the field change over 0.5 s (noise in the gradient)
    assert np.corrcoef(diff.ravel(), 0.5 * rate.ravel())[0, 1] > 0.3
    assert np.abs(diff).max() < 30 * one_nT


def test_tam_scale_and_nonorthogonality_change_the_response(base):
    y0, _, _ = run(base, "TAM1", T1HZ, noise=0.0)
    b0 = np.stack([y0[c] for c in ("bx", "by", "bz")], -1)
    y1, _, _ = run(with_effect(base, "TAM1.scale", 1e-3), "TAM1", T1HZ, noise=0.0)
    b1 = np.stack([y1[c] for c in ("bx", "by", "bz")], -1)
    assert np.allclose(b1, b0 * (1 + 1e-3 * np.array([1.0, -0.7, 0.5])), atol=2e-3)
    y2, _, _ = run(with_effect(base, "TAM1.nonorthogonality", 1e-3), "TAM1", T1HZ, noise=0.0)
    b2 = np.stack([y2[c] for c in ("bx", "by", "bz")], -1)
    P = np.array([[0.0, 1.0, -0.6], [1.0, 0.0, 0.8], [-0.6, 0.8, 0.0]])
    assert np.allclose(b2 - b0, 1e-3 * b0 @ P.T, atol=2e-3)


def test_fhst_rotation_about_boresight(base):
    delta = math.radians(0.1)
    cfg = with_effect(base, "FHST1.alignment", delta, axis=(1, 0, 0))
    a_true = np.radians(cfg.sensor("FHST1").true["alignment_deg"])
    a_book = np.radians(cfg.sensor("FHST1").book["alignment_deg"])
    M_err = R.euler123_to_dcm(*a_true) @ R.euler123_to_dcm(*a_book).T
    assert np.allclose(R.dcm_to_rotvec(M_err), [delta, 0.0, 0.0], atol=1e-12)
    y0, world, _ = run(base, "FHST1", T10, noise=0.0)
    y1, _, _ = run(cfg, "FHST1", T10, noise=0.0)
    same = np.isin(y1["t"], y0["t"])
    assert same.sum() > 20
    k0 = np.searchsorted(y0["t"], y1["t"][same])
    ok = y0["ra"][k0] == y1["ra"][same]
    h0, v0 = y0["h"][k0][ok], y0["v"][k0][ok]
    dh, dv = y1["h"][same][ok] - h0, y1["v"][same][ok] - v0
    # A frame rotation δ about x: F_y' = F_y + δ F_z, F_z' = F_z − δ F_y → Δh ≈ −δ v, Δv ≈ δ h.
    assert np.allclose(dh, -delta * v0, atol=0.2 * one_arcsecond)
    assert np.allclose(dv, delta * h0, atol=0.2 * one_arcsecond)


def test_stellar_aberration_and_misidentification(base):
    y0, world, _ = run(with_effect(base, "model.stellar_aberration", 0.0), "FHST2", T10, noise=0.0)
    y1, _, _ = run(base, "FHST2", T10, noise=0.0)  # real physics: on
    k = np.isin(y1["t"], y0["t"])
    k0 = np.searchsorted(y0["t"], y1["t"][k])
    ok = y0["ra"][k0] == y1["ra"][k]
    shift = np.hypot(y1["h"][k][ok] - y0["h"][k0][ok], y1["v"][k][ok] - y0["v"][k0][ok])
    # |v_earth + v_sc| / c ≲ (30.3 + 7.6) / c = 26"
    assert 3 * one_arcsecond < shift.max() < 27 * one_arcsecond
    y2, _, _ = run(with_effect(base, "FHST2.misidentification", 0.2), "FHST2", T10, noise=0.0)
    ra, dec = np.radians(y2["ra"]), np.radians(y2["dec"])
    F_I = np.stack([np.cos(ra) * np.cos(dec), np.sin(ra) * np.cos(dec), np.sin(dec)], -1)
    M = R.euler123_to_dcm(*np.radians(base.sensor("FHST2").book["alignment_deg"]))
    F_S = np.einsum("ij,njk,nk->ni", M, world.attitude(y2["t"]), F_I)
    wrong = np.abs(np.arcsin(F_S[:, 2]) - y2["h"]) > 10 * one_arcsecond
    assert wrong.mean() == pytest.approx(0.2, abs=0.08)


def test_fss_harmonic_and_css_bias(base):
    H = 5e-5
    swept = nominal_threeaxis("sun_pointing", seed=21, duration_s=D, sweep_deg=3.0)
    y0, _, _ = run(swept, "FSS1", T1HZ)
    y1, world, _ = run(with_effect(swept, "FSS1.harmonic", H), "FSS1", T1HZ)
    tan_a = 7.6e-5 * y0["n_alpha"]  # A1 = 0, A3 = 0 in the book
    expected = -H * np.sin(2 * 50.0 * tan_a) / 7.6e-5  # second harmonic, ±0.66 counts
    dn = y1["n_alpha"] - y0["n_alpha"]
    assert np.max(np.abs(dn - expected)) <= 1.0 + 1e-9
    # The shared Gaussian noise dithers the rounding, so E[Δn | expected] = expected.
    slope = np.sum(dn * expected) / np.sum(expected**2)
    assert slope == pytest.approx(1.0, abs=0.1)
    c0, _, _ = run(base, "CSS1", T1HZ)
    cfg = with_effect(base, "CSS1.bias", math.radians(1.0))
    c1, _, _ = run(cfg, "CSS1", T1HZ)
    b_true = np.asarray(cfg.sensor("CSS1").true["bias"])
    assert np.hypot(*b_true) == pytest.approx(math.radians(1.0))
    K = math.radians(0.25)
    assert np.mean(c1["n_alpha"] - c0["n_alpha"]) == pytest.approx(b_true[0] / K, abs=0.1)
    assert np.mean(c1["n_beta"] - c0["n_beta"]) == pytest.approx(b_true[1] / K, abs=0.1)


def test_gyro_scale_multiplies_the_rate(base):
    y0, world, _ = run(base, "IRU", T1HZ[1:])
    cfg = with_effect(base, "IRU.scale_misalignment", 1e-3)
    y1, _, _ = run(cfg, "IRU", T1HZ[1:])
    w0 = np.stack([y0[c] for c in ("wx", "wy", "wz")], -1)
    w1 = np.stack([y1[c] for c in ("wx", "wy", "wz")], -1)
    w_true = world.omega_avg(T1HZ[1:] - 1.0, T1HZ[1:])
    G = np.asarray(cfg.sensor("IRU").true["G"])
    # (G − I) also scales the wandering bias (|b| ≲ 1e-8 rad/s): 1e-11 rad/s at most
    assert np.allclose(w1 - w0, w_true @ (G - np.eye(3)).T, rtol=0, atol=5e-11)
    assert np.abs(w_true).max() > 5e-4, "the scenario must slew for gyro scale to matter"


def test_every_effect_applies_and_is_listed_in_the_answer_file(tmp_path):
    three = nominal_threeaxis("sun_pointing", seed=1, duration_s=60.0)
    spin = spinner_nominal(seed=1, duration_s=60.0)
    by_type = {s.type: s.name for s in three.sensors + spin.sensors}
    cfg_of = {s.name: (three if s in three.sensors else spin) for s in three.sensors + spin.sensors}
    n = 0
    for effect, types, _unit, _desc in list_effects():
        for typ in types:
            sensor = "model" if typ == "model" else by_type[typ]
            cfg = three if sensor == "model" else cfg_of[sensor]
            out = with_effect(cfg, f"{sensor}.{effect}", 1e-3)
            assert out.effects[-1].id == f"{sensor}.{effect}" and cfg.effects == []
            n += 1
    assert n > 35
    cfg = with_effect(with_effect(three, "TAM1.bias", 50.0), "model.stellar_aberration", 1.0)
    write_mission(cfg, tmp_path / "m", truth_path=tmp_path / "a.json")
    truth = json.loads((tmp_path / "a.json").read_text())
    assert [e["id"] for e in truth["hidden_effects"]] == ["TAM1.bias", "model.stellar_aberration"]
    assert truth["hidden_effects"][1]["sensor"] is None and truth["physics"]["stellar_aberration"] is True
    assert truth["sensors"]["TAM1"]["true"]["bias"] == pytest.approx([30.0, -24.0, 32.0])
    assert "bias = [0.0, 0.0, 0.0]" in (tmp_path / "m" / "mission.toml").read_text()
    with pytest.raises(InputError, match="does not apply"):
        with_effect(three, "FHST1.contamination_mtb_x", 1.0)
    with pytest.raises(InputError, match="no sensor"):
        with_effect(three, "TAM9.bias", 1.0)


def test_physics_switches_and_ephemeris_time_error(tmp_path):
    base = nominal_threeaxis("sun_pointing", seed=3, duration_s=D)
    y0, world, _ = run(base, "FSS1", T1HZ, noise=0.0)
    y1, _, _ = run(with_effect(base, "model.sun_parallax", 0.0), "FSS1", T1HZ, noise=0.0)
    # Parallax |r|/AU ≈ 9.5": about 0.6 count at A2 = 7.6e-5 (16"/count), once per orbit.
    d = np.concatenate([y1["n_alpha"] - y0["n_alpha"], y1["n_beta"] - y0["n_beta"]])
    assert 0 < np.mean(d != 0) < 0.9 and np.abs(d).max() <= 1
    spin = spinner_nominal(seed=2, duration_s=600.0)
    cfg = with_effect(spin, "HS1.d_t", 2.0)
    out = write_mission(cfg, tmp_path / "dt", truth_path=tmp_path / "dt.json")
    eph = np.loadtxt(out / "ephemeris.csv", delimiter=",", skiprows=1)
    r_true, _ = World(cfg).orbit(eph[:, 0] - 2.0)
    assert np.allclose(eph[:, 1:4], r_true, atol=1e-6)
    truth = json.loads((tmp_path / "dt.json").read_text())
    assert truth["ephemeris_time_error_s"] == 2.0 and truth["hidden_effects"][0]["id"] == "HS1.d_t"
