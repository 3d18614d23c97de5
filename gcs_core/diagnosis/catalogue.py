"""The catalogue of candidate effects: what an experienced analyst suspects.

An effect is a group of model parameters that enter and leave the state together
(``<SENSOR>.<effect>``, ICD §7), or an always-on physics correction
(``model.<effect>``). Sensor effects are parameters that each observation model
already declares with analytic partials (:class:`~gcs_core.models.base.ParamSpec`,
``effect`` field), so adding an entry to the catalogue is adding a parameter to one
model module plus, if wanted, an explanation below. Physics effects flip an option of
:class:`~gcs_core.problem.prepare.PhysicsOptions`; their signature is the difference of
the predictions with and without the option.
"""

from __future__ import annotations

from dataclasses import dataclass

from gcs_core.problem.prepare import PHYSICS_EFFECTS

#: effect name -> (family, physical explanation). The explanation says what the
#: signature looks like and what physical cause it points to.
EXPLANATIONS: dict[str, tuple[str, str]] = {
    "bias": (
        "bias",
        "A constant offset of the measurement: electronics offset, or (magnetometer) the "
        "spacecraft's own permanent field. Its signature is a residual that does not average "
        "to zero, whatever the geometry.",
    ),
    "alignment": (
        "alignment",
        "The sensor is mounted rotated from its data-book alignment. The "
        "residual follows the reference vector as it moves in the sensor frame, as a "
        "small rotation would; about an optical boresight it shows as a residual growing "
        "with distance from the centre of the field of view.",
    ),
    "scale": (
        "scale",
        "Scale-factor error: the reading is proportional to the true value with a gain "
        "other than the data book's. The residual grows with the size of the measured "
        "component and changes sign with it.",
    ),
    "nonorthogonality": (
        "scale",
        "The sensor axes are not mutually orthogonal (the symmetric part of "
        "the full 3×3 correction). One axis picks up a fraction of another's field.",
    ),
    "time_offset": (
        "timing",
        "The sensor's clock and the attitude's differ by a constant: the residual "
        "is proportional to how fast the measured vector moves in the sensor frame "
        "(body rate and orbital motion).",
    ),
    "harmonic": (
        "transfer function",
        "A second harmonic in the fine Sun sensor's transfer function "
        "(reticle pattern): the residual oscillates with the Sun angle across the field of "
        "view at twice the fundamental frequency.",
    ),
    "scale_misalignment": (
        "gyro",
        "The gyro scale factors and axis misalignments (the 3×3 matrix G of "
        "Eq 4-32): attitude errors that build up during slews in proportion to "
        "the angle turned.",
    ),
    "bias_instability": (
        "gyro",
        "Gyro bias instability: the drift-rate bias is not constant but "
        "drifts (a rate random walk, thermal settling), here as a linear trend "
        "ḃ over the span. The attitude the gyros carry then bends away from the "
        "other sensors quadratically in time, most at the span's ends.",
    ),
    "horizon_height": (
        "horizon",
        "The height of the CO2 horizon differs from the data book; the "
        "Earth looks larger or smaller, changing the Earth width most.",
    ),
    "oblateness": (
        "horizon",
        "The Earth's flattening differs from WGS-84 by κ f (or, with the "
        "earth_oblateness physics off, the Earth is oblate at all): the angular radius at "
        "each crossing depends on its tangent point's latitude, a residual that follows "
        "the latitudes the scan touches.",
    ),
    "d_gamma": ("horizon", "Scanner mounting-angle bias Δγ (Eq 4-12)."),
    "d_rho": ("horizon", "Bias on the Earth's angular radius Δρ (Eq 4-12)."),
    "d_phi": ("horizon", "Azimuth bias ΔΦ between Sun sensor and horizon scanner (Eq 4-12)."),
    "eps_H": ("horizon", "Earth-sensor plane tilt ε_H (Eq 4-12e)."),
    "d_t": ("horizon", "In-track orbit time error Δt (Eq 4-13)."),
    "tilt": ("sun sensor", "Plane-field Sun-sensor tilt ε_S (Eq 4-14)."),
    "stellar_aberration": (
        "physics",
        "Stellar aberration: the spacecraft's velocity (the Earth's "
        "≈30 km/s about the Sun plus the orbital ≈7.5 km/s) displaces every star by "
        "up to ≈25 arcsec toward the apex of motion. Star-tracker residuals then "
        "follow the velocity direction in the tracker frame.",
    ),
    "solar_aberration": (
        "physics",
        "Aberration of the Sun seen from the moving spacecraft: up to "
        "≈5 arcsec along the orbital velocity, once per orbit.",
    ),
    "sun_parallax": (
        "physics",
        "Solar parallax: the Sun seen from the spacecraft rather than the "
        "Earth's centre, up to ≈9 arcsec, once per orbit.",
    ),
    "earth_oblateness": (
        "physics",
        "The Earth is oblate (WGS-84, f = 1/298.257): the horizon a scan "
        "crosses lies up to 21 km lower over the poles, so the Earth's angular "
        "radius at each crossing depends on the latitude of its tangent point, "
        "20–25° of arc from the sub-satellite point. Horizon residuals follow the "
        "latitudes the scans touch (docs/horizon.md).",
    ),
    "field_model": (
        "physics",
        "Geomagnetic model truncation: a dipole leaves out the higher degrees "
        "of IGRF, hundreds of nT in LEO, following the ground track.",
    ),
    "field": (
        "reference",
        'The reference field of a ground calibration (field_model = "constant"): '
        "one unknown vector of the laboratory frame, the Earth's field as the room distorts "
        "it. Its magnitude and a magnetometer's common scale factor are one quantity.",
    ),
    "field_gradient": (
        "reference",
        "The laboratory field is not uniform: near steel benches, "
        "frames and wiring it changes by µT over the decimetres a unit is carried. "
        "With the sensor's position in the aux channels pos_x/y/z (motion capture), "
        "the field is B_0 + G p with G symmetric and trace-free (a current-free "
        "room), five elements field.G_*. Residuals then follow where the unit was, "
        "not how it was turned.",
    ),
}


def explanation(effect: str) -> tuple[str, str]:
    """(family, explanation) of an effect name; contamination channels share one text, and
    so do the generic families (:mod:`gcs_core.diagnosis.families`)."""
    from gcs_core.diagnosis.families import explanation as family_explanation

    fam = family_explanation(effect)
    if fam is not None:
        return fam
    if effect.startswith("contamination_"):
        ch = effect[len("contamination_") :]
        return (
            "contamination",
            f"Magnetic contamination correlated with the auxiliary channel "
            f"'{ch}': a spacecraft field (torquer coil, current loop, temperature-dependent "
            f"magnetization) proportional to it adds to the measurement. The residual tracks "
            f"'{ch}' in time.",
        )
    return EXPLANATIONS.get(effect, ("other", "An extended model parameter."))


@dataclass(frozen=True)
class Effect:
    """One catalogue entry for a mission.

    Attributes
    ----------
    id : ``<SENSOR>.<effect>`` or ``model.<effect>``.
    sensor : owning sensor, or None for physics effects.
    effect : effect name.
    elements : state elements (sensor effects); empty for physics effects.
    family, explanation : from :data:`EXPLANATIONS`.
    """

    id: str
    sensor: str | None
    effect: str
    elements: tuple[str, ...]
    family: str
    explanation: str

    @property
    def physics(self) -> bool:
        return self.sensor is None


def generic_catalogue() -> list[tuple[str, str, str]]:
    """(effect, family, explanation) for ``gcs effects`` without a mission."""
    rows = [(name, *explanation(name)) for name in EXPLANATIONS]
    rows.append(("contamination_<channel>", *explanation("contamination_<channel>")))
    rows.append(
        (
            "<alignment|bias|scale>_vs_<channel>",
            "drift",
            "A generic family offered when the residual-structure search finds a sensor's residual "
            "following a channel: the sensor's alignment, bias or scale varying linearly with an aux "
            "channel, the orbit phase (orbit1, orbit2: its first and second harmonic) or time "
            "(docs/residual_structure.md).",
        )
    )
    return rows


def mission_catalogue(problem, physics) -> list[Effect]:
    """Every effect of this mission's models and physics, in the state or not."""
    seen: dict[str, Effect] = {}
    for e in problem.state:
        if e.kind != "sensor" or not e.effect:
            continue
        eid = f"{e.sensor}.{e.effect}"
        if eid not in seen:
            fam, text = explanation(e.effect)
            seen[eid] = Effect(eid, e.sensor, e.effect, (), fam, text)
        seen[eid] = Effect(
            eid, e.sensor, e.effect, seen[eid].elements + (e.name,), seen[eid].family, seen[eid].explanation
        )
    _with_intercepts(seen, problem.state)
    types = {sd.model.type_name for sd in problem.sensors}
    relevant = {
        "stellar_aberration": "star_tracker" in types,
        "solar_aberration": bool(types & {"fine_sun", "coarse_sun", "plane_field_sun"}),
        "sun_parallax": bool(types & {"fine_sun", "coarse_sun", "plane_field_sun"}),
        "earth_oblateness": "horizon" in types,
        "field_model": "magnetometer" in types
        and getattr(problem.builder.physics, "field_model", "igrf") != "constant",
    }
    for opt in PHYSICS_EFFECTS:
        if relevant.get(opt):
            fam, text = explanation(opt)
            seen[f"model.{opt}"] = Effect(f"model.{opt}", None, opt, (), fam, text)
    return list(seen.values())


def _with_intercepts(seen: dict[str, Effect], state) -> None:
    """A generic family whose base effect is not estimated carries that effect's elements
    too: ``p(t) = p + k (x − x̄)`` needs ``p`` at the mean of the channel (a magnetometer's
    gain drifting with a temperature is off its data-book value at the mean temperature)."""
    from gcs_core.models.drift import split_family
    from gcs_core.problem.state import HELD

    for eid, e in list(seen.items()):
        parts = split_family(e.effect)
        base = seen.get(f"{e.sensor}.{parts[0]}") if parts is not None else None
        if base is None or not all(state[n].role == HELD for n in base.elements):
            continue
        seen[eid] = Effect(eid, e.sensor, e.effect, e.elements + base.elements, e.family, e.explanation)
