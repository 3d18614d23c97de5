"""Named mission scenarios and hidden-effect builders.

* :func:`nominal_threeaxis` — TAM, IRU, two FHSTs, FSS and CSS on a 520 km, 28.5° orbit,
  in inertial, Earth-pointing or Sun-pointing mode, with slow attitude motion and four
  constant-rate slews (Eq 4-36) so gyro scale factors are observable. Data book = truth.
* :func:`spinner_nominal` — a 10 rpm spinner with a plane-field Sun sensor (PSS1) and a
  horizon scanner (HS1), one row per spin. Data book = truth.
* :func:`with_effect` — a copy of a scenario with one hidden effect: a difference between
  truth and data book, or physics the book does not mention. :data:`EFFECTS` lists them,
  named as in the GCS effect catalogue (``gcs effects``); :data:`MODEL_EFFECTS` are the
  mission-wide physics switches (on in every scenario, as in real data).

Default data-book values mirror the ICD example mission (shared/examples/sunpoint-nominal):
TAM noise 25 nT; IRU σ_v = 3.162278e-7 rad/s^0.5, σ_u = 3.162278e-10 rad/s^1.5;
FHST fov 4°, noise 8″; FSS fov 32°, A2 = 7.6e-5, k = 50, noise 0.577 counts;
CSS fov 60°, K = 0.25°/count, noise 0.577 counts.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gcs_core.errors import InputError
from gcs_core.sim import astro, drifts
from gcs_core.sim._rot import dcm_to_rpy, rotvec_to_dcm, rpy_to_dcm, unit
from gcs_core.sim.astro import R_EARTH_KM
from gcs_core.sim.config import (
    AuxConfig,
    HiddenEffect,
    MissionConfig,
    OnboardConfig,
    OrbitElements,
    SensorConfig,
    Slew,
    SpinProfile,
    ThreeAxisProfile,
)
from gcs_core.sim.truth import World

__all__ = [
    "nominal_threeaxis",
    "spinner_nominal",
    "spinner_two_scanners",
    "sun_synchronous_inclination_deg",
    "with_effect",
    "EFFECTS",
    "list_effects",
]

ARCSEC = np.pi / 180.0 / 3600.0


# --- sensor builders -----------------------------------------------------------------------
def tam(name="TAM1", cadence_s=1.0, alignment_deg=(0.0, 0.0, 0.0)) -> SensorConfig:
    return SensorConfig(
        name,
        "magnetometer",
        cadence_s,
        {"alignment_deg": list(map(float, alignment_deg)), "noise": 25.0, "bias": [0.0, 0.0, 0.0]},
    )


def iru(name="IRU", cadence_s=1.0) -> SensorConfig:
    return SensorConfig(
        name,
        "gyro",
        cadence_s,
        {"alignment_deg": [0.0, 0.0, 0.0], "arw": 3.162278e-07, "rrw": 3.162278e-10, "bias": [0.0, 0.0, 0.0]},
    )


def fhst(name, alignment_deg, cadence_s=10.0) -> SensorConfig:
    return SensorConfig(
        name,
        "star_tracker",
        cadence_s,
        {"alignment_deg": list(map(float, alignment_deg)), "fov_deg": 4.0, "noise": 3.878509e-05, "scale": [1.0, 1.0]},
        {"sun_exclusion_deg": 30.0, "earth_exclusion_deg": 10.0},
    )


def fss(name="FSS1", alignment_deg=(0.0, 0.0, 0.0), cadence_s=1.0) -> SensorConfig:
    return SensorConfig(
        name,
        "fine_sun",
        cadence_s,
        {
            "alignment_deg": list(map(float, alignment_deg)),
            "fov_deg": 32.0,
            "noise": 0.577,
            "coeff_alpha": [0.0, 7.6e-05, 0.0, 50.0],
            "coeff_beta": [0.0, 7.6e-05, 0.0, 50.0],
        },
    )


def css(name="CSS1", alignment_deg=(0.0, 0.0, 0.0), cadence_s=1.0) -> SensorConfig:
    k = float(np.radians(0.25))
    return SensorConfig(
        name,
        "coarse_sun",
        cadence_s,
        {
            "alignment_deg": list(map(float, alignment_deg)),
            "fov_deg": 60.0,
            "noise": 0.577,
            "scale": [k, k],
            "bias": [0.0, 0.0],
        },
    )


def default_slews(duration_s: float) -> list[Slew]:
    """Roll out and back (~24°), a pitch and a yaw step (~5.6°), at 22/45/60/75 % of the span."""
    D = duration_s
    return [
        Slew(0.22 * D, 600.0, "roll", 0.04),
        Slew(0.45 * D, 300.0, "pitch", 0.02),
        Slew(0.60 * D, 300.0, "yaw", -0.02),
        Slew(0.75 * D, 600.0, "roll", -0.04),
    ]


def nominal_threeaxis(
    mode: str = "sun_pointing",
    seed: int = 1,
    duration_s: float = 7200.0,
    *,
    name: str | None = None,
    epoch: str = "2024-05-14T04:00:00Z",
    orbit: OrbitElements | None = None,
    sweep_deg: float = 0.0,
) -> MissionConfig:
    """A three-axis mission with TAM1, IRU, FHST1, FHST2, FSS1, CSS1 (no hidden effect).

    ``sweep_deg`` > 0 adds a slow pitch and yaw sinusoid of that amplitude (periods 2300 s and
    1700 s), a calibration sweep that carries the Sun across the Sun sensors' fields of view.
    """
    if mode not in ("inertial", "earth_pointing", "sun_pointing"):
        raise InputError(f"unknown three-axis mode '{mode}'", key="mode")
    p = ThreeAxisProfile(slews=default_slews(duration_s))
    cfg = MissionConfig(
        name=name or f"nominal-{mode.replace('_', '')}",
        epoch=epoch,
        attitude_mode=mode,
        duration_s=float(duration_s),
        orbit=orbit or OrbitElements(),
        attitude=p,
        aux=AuxConfig(cadence_s=1.0 if duration_s <= 86400 else 10.0),
        onboard=OnboardConfig(error_deg=(0.03, -0.04, 0.0)),
        seed=int(seed),
    )
    if sweep_deg > 0:
        p.wobble_amp_deg = (p.wobble_amp_deg[0], float(sweep_deg), float(sweep_deg))
        p.wobble_period_s = (p.wobble_period_s[0], 2300.0, 1700.0)
    sun_align, fhst1 = (0.0, 0.0, 0.0), (0.0, 0.0, 90.0)
    if mode == "inertial":
        # Point body x at the Sun at the epoch (the Sun-pointing frame frozen at t = 0).
        probe = MissionConfig(name="probe", epoch=epoch, attitude_mode="sun_pointing", duration_s=1.0, orbit=cfg.orbit)
        A0 = World(probe).reference(np.array([0.0]))[0]
        r0, p0, y0 = (float(np.degrees(x)) for x in dcm_to_rpy(A0))
        p.rpy0_deg = (r0, p0, y0)
    elif mode == "earth_pointing":
        # Sun sensors look at the zenith, tilted toward the Sun's side of the orbit plane by the
        # beta angle; FHST1 looks along ±y away from the Sun, raised 30° toward the zenith.
        w = World(cfg)
        r, v = w.orbit(np.array([0.0]))
        s = unit(w.sun(np.array([0.0])))
        beta = float(np.arcsin(np.clip(np.dot(unit(np.cross(r, v))[0], s[0]), -1, 1)))
        sun_align = (float(np.degrees(-beta)), 90.0, 0.0)
        fhst1 = (-30.0, 0.0, 90.0) if beta > 0 else (30.0, 0.0, -90.0)  # 30° above the horizon
    cfg.sensors = [
        tam(),
        iru(),
        fhst("FHST1", fhst1),
        fhst("FHST2", (30.0, 75.0, 0.0)),
        fss(alignment_deg=sun_align),
        css(alignment_deg=sun_align),
    ]
    return cfg


def spinner_nominal(
    seed: int = 1, duration_s: float = 10800.0, *, name: str = "spinner-nominal", epoch: str = "2024-09-02T10:00:00Z"
) -> MissionConfig:
    """A 10 rpm spinner: PSS1 (plane-field Sun sensor) and HS1 (horizon scanner), one row per spin."""
    pss = SensorConfig("PSS1", "plane_field_sun", 0.0, {"tilt_deg": 0.0, "bias": 0.0, "noise": float(np.radians(0.05))})
    hs = SensorConfig(
        "HS1", "horizon", 0.0, {"gamma_deg": 80.0, "phi_h_deg": 40.0, "horizon_height_km": 40.0, "noise": 0.0015}
    )
    return MissionConfig(
        name=name,
        epoch=epoch,
        attitude_mode="spinning",
        duration_s=float(duration_s),
        orbit=OrbitElements(a_km=7078.137, e=0.001, i_deg=28.5, raan_deg=35.0, argp_deg=60.0, mean_anomaly_deg=10.0),
        attitude=SpinProfile(ra_deg=320.0, dec_deg=50.0, rate_rpm=10.0, phase0_deg=17.0),
        sensors=[pss, hs],
        aux=None,
        onboard=None,
        seed=int(seed),
    )


#: Earth's J2 and GM, for the Sun-synchronous inclination (Vallado 2013, Table D-2 / D-3)
_J2, _MU_KM3_S2 = 1.08262668e-3, 398600.4418
#: nodal rate of a Sun-synchronous orbit: 360° per tropical year [rad/s]
_SSO_NODE_RATE = 2.0 * np.pi / (365.2421897 * 86400.0)


def sun_synchronous_inclination_deg(a_km: float, e: float = 0.0) -> float:
    """Inclination whose secular J2 nodal drift follows the mean Sun:
    ``cos i = −Ω̇ 2 a^{7/2} (1 − e²)² / (3 J2 R_E² √μ)`` (Vallado 2013, Eq 11-14)."""
    c = -_SSO_NODE_RATE * 2.0 * a_km**3.5 * (1 - e * e) ** 2 / (3.0 * _J2 * R_EARTH_KM**2 * np.sqrt(_MU_KM3_S2))
    return float(np.degrees(np.arccos(c)))


def spinner_two_scanners(
    seed: int = 1,
    *,
    inclination_deg: float | str = 28.5,
    duration_s: float = 10800.0,
    altitude_km: float = 700.0,
    axis_tilt_deg: float = 30.0,
    name: str | None = None,
    epoch: str = "2024-09-02T10:00:00Z",
) -> MissionConfig:
    """A 10 rpm spinner at any inclination (``"sso"``: Sun-synchronous at that altitude):
    PSS1 (plane-field Sun sensor) and two horizon scanners on the cones the real missions
    use, HS1 at γ = 60° and HS2 at γ = 110°. The spin axis is the orbit normal at the epoch
    tilted by ``axis_tilt_deg`` toward the Sun's side, so both cones cross the Earth over
    the whole orbit (nadir angle 90° ± the tilt) and the Sun stays well off the axis.
    Data book = truth; the horizon is the WGS-84 ellipsoid (``physics``)."""
    a_km = R_EARTH_KM + altitude_km
    inc = sun_synchronous_inclination_deg(a_km, 0.001) if inclination_deg == "sso" else float(inclination_deg)
    label = "sso" if inclination_deg == "sso" else f"i{inc:g}"
    raan = 35.0
    i, O = np.radians(inc), np.radians(raan)
    normal = np.array([np.sin(i) * np.sin(O), -np.sin(i) * np.cos(O), np.cos(i)])
    sun = unit(astro.sun_position_km(astro.epoch_jd(astro.parse_epoch(epoch)), np.array([0.0]))[0])
    side = unit(sun - np.dot(sun, normal) * normal)
    tilt = np.radians(axis_tilt_deg)
    A = np.cos(tilt) * normal + np.sin(tilt) * side
    ra, dec = float(np.degrees(np.arctan2(A[1], A[0])) % 360.0), float(np.degrees(np.arcsin(A[2])))
    pss = SensorConfig("PSS1", "plane_field_sun", 0.0, {"tilt_deg": 0.0, "bias": 0.0, "noise": float(np.radians(0.05))})
    hs = [
        SensorConfig(n, "horizon", 0.0, {"gamma_deg": g, "phi_h_deg": p, "horizon_height_km": 40.0, "noise": 0.0015})
        for n, g, p in (("HS1", 60.0, 35.0), ("HS2", 110.0, 215.0))
    ]
    return MissionConfig(
        name=name or f"spinner-{label}-s{seed}",
        epoch=epoch,
        attitude_mode="spinning",
        duration_s=float(duration_s),
        orbit=OrbitElements(a_km=a_km, e=0.001, i_deg=inc, raan_deg=raan, argp_deg=60.0, mean_anomaly_deg=10.0),
        attitude=SpinProfile(ra_deg=ra, dec_deg=dec, rate_rpm=10.0, phase0_deg=17.0),
        sensors=[pss, *hs],
        aux=None,
        onboard=None,
        seed=int(seed),
    )


# --- hidden effects ------------------------------------------------------------------------
@dataclass(frozen=True)
class EffectSpec:
    """One kind of hidden effect: where it applies, its unit and how it changes the truth."""

    types: tuple[str, ...]
    unit: str
    description: str
    apply: Callable[[SensorConfig, float, dict], None] | None  # None: set on the mission (d_t)


def _pattern(n, axis):
    v = np.asarray(axis if axis is not None else (0.6, -0.48, 0.64)[:n], dtype=float)
    return v / np.linalg.norm(v)


def _bias(s: SensorConfig, m: float, kw: dict) -> None:
    if s.type == "plane_field_sun":
        s.true["bias"] = float(s.book["bias"]) + m
        return
    b = np.asarray(s.book["bias"], dtype=float)
    s.true["bias"] = (b + m * _pattern(b.size, kw.get("axis"))).tolist()


def _alignment(s, m, kw):
    a = np.radians(np.asarray(s.book["alignment_deg"], dtype=float))
    delta = m * _pattern(3, kw.get("axis", (0.36, 0.48, 0.8)))
    M_true = rotvec_to_dcm(delta) @ rpy_to_dcm(a[0], a[1], a[2])
    s.true["alignment_deg"] = [float(np.round(np.degrees(x), 12)) + 0.0 for x in dcm_to_rpy(M_true)]
    s.true["misalignment_rad"] = delta.tolist()


def _scale(s, m, kw):
    if s.type == "magnetometer":
        K = np.asarray(s.true.get("response", np.eye(3)), dtype=float).copy()
        s.true["response"] = (K + np.diag(m * np.array([1.0, -0.7, 0.5]))).tolist()
    elif s.type in ("star_tracker", "coarse_sun"):
        s.true["scale"] = (np.asarray(s.book["scale"], dtype=float) * (1.0 + m * np.array([1.0, -0.7]))).tolist()


def _nonorth(s, m, kw):
    K = np.asarray(s.true.get("response", np.eye(3)), dtype=float).copy()
    K += m * np.array([[0.0, 1.0, -0.6], [1.0, 0.0, 0.8], [-0.6, 0.8, 0.0]])
    s.true["response"] = K.tolist()


def _gyro_g(s, m, kw):
    P = np.asarray(kw.get("pattern", [[1.0, 0.6, -0.4], [-0.3, -0.7, 0.5], [0.8, 0.2, 0.5]]), dtype=float)
    s.true["G"] = (np.eye(3) + m * P).tolist()


def _contamination(channel):
    def apply(s, m, kw):
        c = dict(s.true.get("contamination", {}))
        c[channel] = (m * _pattern(3, kw.get("axis", (0.8, -0.5, 0.33)))).tolist()
        s.true["contamination"] = c

    return apply


def _set(key, base_key=None, convert=lambda m: m):
    def apply(s, m, kw):
        base = float(s.book.get(base_key, 0.0)) if base_key else 0.0
        s.true[key] = base + convert(m)

    return apply


def _transfer(s, m, kw):
    a, b = list(s.book["coeff_alpha"]), list(s.book["coeff_beta"])
    a[0], a[2] = a[0] + m, a[2] + m
    b[0], b[2] = b[0] - 0.6 * m, b[2] + 0.8 * m
    s.true["coeff_alpha"], s.true["coeff_beta"] = a, b


def _tilt(s: SensorConfig, m: float, kw: dict) -> None:
    s.true["tilt_deg"] = float(s.book["tilt_deg"]) + float(np.degrees(m))


def _drift(key: str, default_axis=None, pattern=None):
    """A drift of the sensor's own physics (:mod:`gcs_core.sim.drifts`) on ``tam_temp``."""

    def apply(s, m, kw):
        spec = {"channel": "tam_temp", "ref": float(kw.get("ref", 22.0)), "rate": float(m)}
        if default_axis is not None:
            spec["axis"] = list(kw.get("axis", default_axis))
        if pattern is not None:
            spec["rate"] = [float(m) * x for x in pattern]
        s.true[key] = spec

    return apply


#: phase φ [rad] of the once-per-orbit tilt ``A sin(u + φ)`` (gcs_core/sim/drifts.py)
ORBIT_BEND_PHASE = 0.7


def _orbit_bend(s, m, kw):
    s.true["orbit_bend"] = {
        "amplitude": float(m),
        "axis": list(kw.get("axis", (0.0, 1.0, 0.0))),
        "phase": ORBIT_BEND_PHASE,
    }


_VEC3 = ("magnetometer", "gyro", "star_tracker", "fine_sun", "coarse_sun")
#: Sensor effects by catalogue name (``gcs effects``): the id is ``<SENSOR>.<name>``.
EFFECTS: dict[str, EffectSpec] = {
    "bias": EffectSpec(
        ("magnetometer", "gyro", "coarse_sun", "plane_field_sun"),
        "nT | rad/s | rad",
        "bias added to the book value, direction (0.6, -0.48, 0.64) unless axis= "
        "(CSS: (b_α, b_β) ∝ (0.6, -0.48); plane-field: Δβ)",
        _bias,
    ),
    "alignment": EffectSpec(
        _VEC3,
        "rad",
        "sensor frame rotated, M_true = exp(-[δx]) M_book, δ = m·axis "
        "(default axis (0.36, 0.48, 0.8); axis=(1, 0, 0) turns an optical sensor about "
        "its boresight)",
        _alignment,
    ),
    "scale": EffectSpec(
        ("magnetometer", "star_tracker", "coarse_sun"),
        "1",
        "gains 1 + m·(1, -0.7, 0.5) (TAM response diagonal), S_H, S_V or K_α, K_β times 1 + m·(1, -0.7)",
        _scale,
    ),
    "nonorthogonality": EffectSpec(
        ("magnetometer",), "1", "symmetric off-diagonal TAM response m·[[0,1,-.6],[1,0,.8],[-.6,.8,0]]", _nonorth
    ),
    "bias_instability": EffectSpec(
        ("gyro",),
        "rad/s^2",
        "linear gyro bias drift ḃ = m·(0.6, -0.48, 0.64)",
        lambda s, m, kw: s.true.__setitem__("bias_rate", [0.6 * float(m), -0.48 * float(m), 0.64 * float(m)]),
    ),
    "scale_misalignment": EffectSpec(
        ("gyro",), "1", "G = I + m·P, P = [[1,.6,-.4],[-.3,-.7,.5],[.8,.2,.5]] unless pattern= (Eq 4-32)", _gyro_g
    ),
    "contamination_mtb_x": EffectSpec(
        ("magnetometer",), "nT/(A m^2)", "TAM reads m·(0.8,-0.5,0.33)/|.|·mtb_x", _contamination("mtb_x")
    ),
    "contamination_mtb_y": EffectSpec(
        ("magnetometer",), "nT/(A m^2)", "TAM reads m·(0.8,-0.5,0.33)/|.|·mtb_y", _contamination("mtb_y")
    ),
    "contamination_mtb_z": EffectSpec(
        ("magnetometer",), "nT/(A m^2)", "TAM reads m·(0.8,-0.5,0.33)/|.|·mtb_z", _contamination("mtb_z")
    ),
    "time_offset": EffectSpec(
        _VEC3 + ("plane_field_sun", "horizon"), "s", "a row stamped t is measured at t + m", _set("time_offset_s")
    ),
    "transfer_function": EffectSpec(
        ("fine_sun",), "1 (tan)", "FSS A1 += m, A3 += m, B1 -= 0.6 m, B3 += 0.8 m (Eq 4-23)", _transfer
    ),
    "harmonic": EffectSpec(
        ("fine_sun",),
        "1 (tan)",
        "FSS second harmonic H sin(2k tan) of the transfer function, H_α = m, H_β = -0.8 m",
        lambda s, m, kw: s.true.__setitem__("harmonic", [float(m), -0.8 * float(m)]),
    ),
    "misidentification": EffectSpec(
        ("star_tracker",),
        "1 (fraction)",
        "fraction of rows reporting a wrong catalog star",
        lambda s, m, kw: s.true.__setitem__("misid_fraction", float(m)),
    ),
    "tilt": EffectSpec(
        ("plane_field_sun",),
        "rad",
        "plane-field sensor tilt ε_S (tilt_deg += m), shared by the horizon timing (Eq 4-12d, 4-14)",
        _tilt,
    ),
    "alignment_vs_tam_temp": EffectSpec(
        ("star_tracker",),
        "rad/°C",
        "the optics bend thermo-elastically: frame turned by m·(tam_temp − 22 °C) about axis "
        "(default (0, 1, 0), a focal-plane axis; (1, 0, 0) the boresight)",
        _drift("bend", default_axis=(0.0, 1.0, 0.0)),
    ),
    "alignment_vs_orbit1": EffectSpec(
        ("star_tracker",),
        "rad",
        "frame turned by m·sin(u + 0.7) about axis (default (0, 1, 0)), u the argument of latitude",
        _orbit_bend,
    ),
    "magnitude_error": EffectSpec(
        ("star_tracker",),
        "rad/mag",
        "centroid h displaced by m·(star magnitude − 4) (no model family holds it)",
        lambda s, m, kw: s.true.__setitem__("mag_error", {"rate": float(m), "ref": 4.0}),
    ),
    "bias_vs_tam_temp": EffectSpec(
        ("fine_sun",),
        "tan/°C",
        "FSS offsets A1, B1 move by m·(1, −0.6)·(tam_temp − 22 °C)",
        _drift("bias_drift", pattern=(1.0, -0.6)),
    ),
    "scale_vs_tam_temp": EffectSpec(
        ("magnetometer",),
        "1/°C",
        "TAM gains move by m·(1, −0.7, 0.5)·(tam_temp − 22 °C)",
        _drift("scale_drift"),
    ),
    "bias_vs_iru_heater": EffectSpec(
        ("gyro",),
        "rad/s",
        "the drift-rate bias steps by m·(0.6, −0.48, 0.64) while the IRU heater is on (aux iru_heater, "
        "a thermostat's duty cycle, written only with this effect)",
        drifts.heater_effect,
    ),
    "d_gamma": EffectSpec(("horizon",), "rad", "scanner cone half-angle bias Δγ", _set("d_gamma")),
    "d_phi": EffectSpec(("horizon",), "rad", "scanner azimuth bias ΔΦ", _set("d_phi")),
    "d_rho": EffectSpec(("horizon",), "rad", "Earth angular radius bias Δρ", _set("d_rho")),
    "eps_H": EffectSpec(("horizon",), "rad", "horizon sensor plane tilt ε_H (Eq 4-12e)", _set("eps_H")),
    "horizon_height": EffectSpec(
        ("horizon",), "km", "true horizon height = book + m", _set("horizon_height_km", "horizon_height_km")
    ),
    "oblateness": EffectSpec(
        ("horizon",),
        "1 (x WGS-84 f)",
        "the Earth this scanner sees is flattened "
        "by m/298.257 more than the physics' (WGS-84, or none with "
        "model.earth_oblateness off)",
        _set("flattening_excess"),
    ),
    "d_t": EffectSpec(
        ("horizon",),
        "s",
        "in-track time error of the ephemeris: row t holds the orbit "
        "at t - m (Eq 4-13; affects every sensor of the mission)",
        None,
    ),
}
#: Mission-wide physics switches, id ``model.<name>``: on in every scenario (real data);
#: with_effect(..., "model.X", 0) gives data without it, 1 records it as an expected discovery.
MODEL_EFFECTS = {
    "stellar_aberration": ("1 (on)", "star directions aberrated by (v_earth + v_sc)/c, up to 26 arcsec"),
    "solar_aberration": ("1 (on)", "Sun direction aberrated by the spacecraft velocity v_sc/c, up to 5 arcsec"),
    "sun_parallax": ("1 (on)", "Sun seen from the spacecraft (s - r) instead of the Earth's centre, ~9 arcsec"),
    "earth_oblateness": (
        "1 (on)",
        "horizon on the WGS-84 ellipsoid (f = 1/298.257) under the CO2 layer, "
        "crossed exactly at each scan's tangent point",
    ),
}


def list_effects() -> list[tuple[str, tuple[str, ...], str, str]]:
    """``(effect, sensor types, unit, description)`` of every hidden effect, model ones last."""
    out = [(k, v.types, v.unit, v.description) for k, v in EFFECTS.items()]
    out += [(k, ("model",), u, d) for k, (u, d) in MODEL_EFFECTS.items()]
    return out


def with_effect(
    base: MissionConfig,
    effect_id: str,
    magnitude: float,
    *,
    name: str | None = None,
    axis=None,
    pattern=None,
    description: str | None = None,
) -> MissionConfig:
    """Copy of ``base`` with one hidden effect ``<SENSOR>.<effect>`` (or ``model.<effect>``).

    ``magnitude`` is in the unit of :data:`EFFECTS` (see :func:`list_effects`); ``axis``
    chooses the direction of vector effects (e.g. ``(1, 0, 0)``: about the boresight),
    ``pattern`` the 3×3 shape of the gyro ``scale_misalignment``. ``model.<physics>`` switches
    physics on (magnitude ≠ 0, recorded) or off (magnitude 0, recorded in truth.json
    ``physics`` only).
    """
    cfg = base.copy()
    if name:
        cfg.name = name
    sensor_name, _, effect = effect_id.partition(".")
    kw = {k: v for k, v in (("axis", axis), ("pattern", pattern)) if v is not None}
    if cfg.aux is not None:
        kw["ref"] = cfg.aux.temp_mean_c  # drifts on tam_temp are about its mean
    if sensor_name == "model":
        if effect not in MODEL_EFFECTS:
            raise InputError(f"unknown model effect '{effect}'", key="effect_id")
        cfg.physics[effect] = bool(magnitude)
        if not magnitude:
            return cfg
        unit_, desc = MODEL_EFFECTS[effect]
    else:
        try:
            s = cfg.sensor(sensor_name)
        except KeyError:
            raise InputError(f"no sensor '{sensor_name}' in mission '{cfg.name}'", key="effect_id") from None
        spec = EFFECTS.get(effect)
        if spec is None or s.type not in spec.types:
            raise InputError(f"effect '{effect}' does not apply to {s.type} {sensor_name}", key="effect_id")
        if effect == "d_t":
            cfg.ephemeris_time_error_s = float(magnitude)
        elif spec.apply is not None:
            spec.apply(s, float(magnitude), kw)
            drifts.with_heater(cfg, effect)
        unit_, desc = spec.unit, spec.description
    cfg.effects.append(HiddenEffect(effect_id, float(magnitude), unit_, description or desc))
    return cfg
