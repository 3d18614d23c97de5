"""Spinner truth: root-found horizon crossings and Sun sightings against the ICD closed form.

The simulator finds the crossings by root finding on the true geometry (gcs_core.sim.spinner);
here the ICD §5 closed form (Eq 4-12 to 4-14, fixed-point iteration on dt) is written out
independently and must agree to far below the scanner noise, for every bias the ICD names.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gcs_core import units
from gcs_core.sim.scenarios import spinner_nominal, with_effect
from gcs_core.sim.spinner import SunSightings
from gcs_core.sim.truth import World
from gcs_core.sim.writer import make_sensor_sim, write_mission

one_microsecond = 1e-6


def apparent_sun(world, t):
    """Ŝ from the spacecraft with orbital aberration (the data's real physics)."""
    r, v = world.orbit(t)
    S = world.sun(t) - r
    S /= np.linalg.norm(S, axis=1)[:, None]
    S = S + v / units.C_KM_S - np.sum(S * v / units.C_KM_S, 1)[:, None] * S
    return S / np.linalg.norm(S, axis=1)[:, None]


def icd_dt(
    world, t_s, dt0, w, *, gamma, phi_h, h_H, d_gamma=0.0, d_phi=0.0, eps_s=0.0, eps_h=0.0, d_rho=0.0, out=False
):
    """ICD §5 horizon model, iterated at the crossing time (Eq 4-12a to 4-12e)."""
    A = world.spin_axis_I
    g = gamma + d_gamma
    dt = dt0.copy()
    for _ in range(6):
        t = t_s + dt
        r, _ = world.orbit(t)
        S = apparent_sun(world, t)
        rn = np.linalg.norm(r, axis=1)
        E = -r / rn[:, None]
        eta = np.arccos(E @ A)
        rho = np.arcsin((units.R_EARTH_KM + h_H) / rn) + d_rho
        Mh = np.cross(A, E) / np.sin(eta)[:, None]
        Nh = np.cross(E, Mh)
        cL = (np.cos(g) - np.cos(rho) * np.cos(eta)) / (np.sin(rho) * np.sin(eta))
        sL = np.sqrt(1 - cL**2) * (1.0 if out else -1.0)
        H = np.cos(rho)[:, None] * E + np.sin(rho)[:, None] * (Mh * sL[:, None] + Nh * cL[:, None])
        Phi = np.arctan2(np.cross(S, H) @ A, np.sum(S * H, 1) - (S @ A) * (H @ A))
        dPS = np.arcsin(np.tan(eps_s) / np.tan(np.arccos(S @ A)))
        dPH = np.arcsin(np.tan(eps_h) / np.tan(g))
        dt = np.mod(Phi - phi_h - d_phi - dPS + dPH, 2 * np.pi) / w
    return dt


CASES = [
    (None, 0.0),
    ("HS1.d_gamma", 0.01),
    ("HS1.d_phi", 0.02),
    ("PSS1.tilt", 0.03),
    ("HS1.eps_H", 0.02),
    ("HS1.horizon_height", 15.0),
    ("HS1.d_rho", 0.004),
    ("PSS1.bias", 0.01),
]


@pytest.mark.parametrize("effect,magnitude", CASES)
def test_root_found_crossings_match_icd_closed_form(effect, magnitude):
    base = spinner_nominal(seed=5, duration_s=1000.0)
    base.physics["earth_oblateness"] = False  # the ICD's spherical Earth
    cfg = base if effect is None else with_effect(base, effect, magnitude)
    hs, pss = cfg.sensor("HS1"), cfg.sensor("PSS1")
    hs.true["noise"] = pss.true["noise"] = 0.0
    world = World(cfg)
    sight = SunSightings(world, pss)
    h_sim = make_sensor_sim(hs, world, np.random.default_rng(0), sightings=sight)
    p_sim = make_sensor_sim(pss, world, np.random.default_rng(0), sightings=sight)
    d = h_sim.run_span(0.0, 1000.0, 980.0)
    p = p_sim.run_span(0.0, 1000.0, 980.0)
    assert d["t"].size > 120 and p["t"].size >= d["t"].size
    kw = dict(
        gamma=math.radians(hs.value("gamma_deg")),
        phi_h=math.radians(hs.value("phi_h_deg")),
        h_H=hs.value("horizon_height_km"),
        d_gamma=hs.value("d_gamma", 0.0),
        d_phi=hs.value("d_phi", 0.0),
        eps_s=math.radians(pss.value("tilt_deg")),
        eps_h=hs.value("eps_H", 0.0),
        d_rho=hs.value("d_rho", 0.0),
    )
    for col, out in (("dt_in", False), ("dt_out", True)):
        ref = icd_dt(world, d["t"], d[col], d["spin_rate"], out=out, **kw)
        assert np.max(np.abs(ref - d[col])) < 5 * one_microsecond, col
    # Plane-field Sun sensor, Eq 4-14: β_m = acos(Â·Ŝ / cos ε_S) + Δβ at the sighting time.
    S = apparent_sun(world, p["t"])
    beta = np.arccos((S @ world.spin_axis_I) / math.cos(kw["eps_s"])) + pss.value("bias")
    assert np.max(np.abs(beta - p["beta"])) < 1e-9


def test_oblate_crossings_are_tangent_to_the_ellipsoid():
    """The simulator's closed-form tangent in the beam's vertical plane against a second
    exact criterion: scaled by ``D = diag(1/a, 1/a, 1/b)`` the ellipsoid is the unit sphere,
    and the beam at each crossing must be tangent to it: ``∠(D d, −D r) = asin(1/|D r|)``."""
    cfg = spinner_nominal(seed=5, duration_s=1000.0)
    cfg.orbit.i_deg = 90.0  # the poles: the largest flattening effect
    hs = cfg.sensor("HS1")
    hs.true["noise"] = 0.0
    world = World(cfg)
    sight = SunSightings(world, cfg.sensor("PSS1"))
    sim = make_sensor_sim(hs, world, np.random.default_rng(0), sightings=sight)
    d = sim.run_span(0.0, 1000.0, 980.0)
    assert d["t"].size > 100
    a, b = sim.axes[0], sim.axes[2]
    assert a - b == pytest.approx(units.R_EARTH_KM / 298.257223563, rel=1e-9)
    D = np.array([1 / a, 1 / a, 1 / b])
    for col in ("dt_in", "dt_out"):
        t = d["t"] + d[col]
        r, _ = world.orbit(t)
        p, q = r * D, sim.los_I(t) * D
        ang = np.arccos(-np.sum(p * q, 1) / (np.linalg.norm(p, axis=1) * np.linalg.norm(q, axis=1)))
        off = ang - np.arcsin(1.0 / np.linalg.norm(p, axis=1))
        # a microsecond of the 10 rpm scan is 1e-6 rad of beam motion
        assert np.max(np.abs(off)) < 2e-6, col


def test_spinner_mission_files_one_row_per_spin(tmp_path):
    cfg = spinner_nominal(seed=3, duration_s=9000.0)
    out = write_mission(cfg, tmp_path / "s", truth_path=tmp_path / "s.json")
    truth = json.loads((tmp_path / "s.json").read_text())
    pss = np.loadtxt(out / "telemetry/PSS1.csv", delimiter=",", skiprows=1)
    hs = np.loadtxt(out / "telemetry/HS1.csv", delimiter=",", skiprows=1)
    assert (out / "telemetry/HS1.csv").read_text().splitlines()[0] == "t,spin_rate,dt_in,dt_out"
    assert (out / "telemetry/PSS1.csv").read_text().splitlines()[0] == "t,beta"
    period = 6.0  # 10 rpm
    steps = np.diff(pss[:, 0])
    assert np.median(steps) == pytest.approx(period, abs=1e-3)
    assert np.all(steps > 0.99 * period)
    assert np.all((hs[:, 2:] > 0) & (hs[:, 2:] < period))
    assert np.allclose(hs[:, 1], 2 * np.pi / period)
    assert set(hs[:, 0]) <= set(pss[:, 0])
    assert "spin_axis_guess_deg" in (out / "mission.toml").read_text()
    assert truth["spin_axis_deg"] == [cfg.attitude.ra_deg, cfg.attitude.dec_deg]
    # Eclipse: the spinner sees no Sun for a while, so there is a gap of many spins.
    assert steps.max() > 600.0


def test_horizon_oblateness_and_time_offset_act_as_physics():
    base = spinner_nominal(seed=5, duration_s=1200.0)
    runs = {}
    for eid, m in ((None, 0.0), ("HS1.oblateness", 1.0), ("HS1.time_offset", 0.5)):
        cfg = base if eid is None else with_effect(base, eid, m)
        cfg.sensor("HS1").true["noise"] = 0.0
        world = World(cfg)
        sight = SunSightings(world, cfg.sensor("PSS1"))
        runs[eid] = make_sensor_sim(cfg.sensor("HS1"), world, np.random.default_rng(0), sightings=sight).run_span(
            0.0, 1200.0, 1180.0
        )
    nominal, oblate, shifted = runs[None], runs["HS1.oblateness"], runs["HS1.time_offset"]
    width = lambda d: d["dt_out"] - d["dt_in"]
    n = min(nominal["t"].size, oblate["t"].size)
    # A smaller polar radius narrows the Earth seen by the scanner by up to ~21 km / 7000 km.
    assert 0.0 < np.max(width(nominal)[:n] - width(oblate)[:n]) < 0.02
    assert np.allclose(shifted["t"], nominal["t"] - 0.5)
    assert np.allclose(shifted["dt_in"], nominal["dt_in"])


def test_simulator_imports_no_model_code():
    """The simulator checks the models, so it must not share their code (issue 11)."""
    import subprocess
    import sys

    code = (
        "import sys, gcs_core.sim, gcs_core.sim.spinner, gcs_core.sim.writer; "
        "print(sorted(m for m in sys.modules if m.startswith(('gcs_core.models', 'gcs_core.ephem', "
        "'gcs_core.frames'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
