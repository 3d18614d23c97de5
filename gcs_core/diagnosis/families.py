"""Generic candidate families offered from what the residual-structure search finds.

A dependency of sensor Y's residual on a channel (:mod:`gcs_core.diagnosis.structure`)
becomes candidates on Y: each of its drifting effects (alignment, bias, scale) varying
linearly with that channel (:mod:`gcs_core.models.drift`). An aux channel gives one family
per effect (``alignment_vs_tam_temp``); the orbit phase, the Sun angle or the eclipse (all
following the orbit) give the orbit phase's first and second harmonics
(``alignment_vs_orbit1``, ``..._vs_orbit2``); time gives a drift (``bias_vs_time``). An aux
channel that is an alias of the orbit phase, and aux aliases of the channel found, are
offered too: the ranking's alias rule then keeps the one the data prefer, the simplest on
a tie (:func:`gcs_core.diagnosis.policy.parsimonious`).

Channels of other kinds (the position in the field of view, the body rate, telemetry such
as a star's magnitude) have no family: the catalogue's forms (alignment, scale, time
offset) or nothing hold them, and the report says so.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from gcs_core.diagnosis.structure import Dependency
from gcs_core.models.drift import DRIFTING, ORBIT_TAGS, TIME_TAG, drifting_params, split_family

#: aux channels no family is made on: a magnetometer's position in a laboratory (the
#: catalogue's field_gradient is a field that follows it)
POSITION = ("aux:pos_x", "aux:pos_y", "aux:pos_z")
#: what a drifting effect following each kind of channel physically is
PHYSICS: dict[tuple[str, str], str] = {
    ("alignment", "temperature"): "thermo-elastic bending",
    ("alignment", "orbit"): "thermal bending over the orbit",
    ("alignment", "time"): "mount creep (a drifting alignment)",
    ("alignment", "aux"): "a mount that moves with",
    ("bias", "temperature"): "thermal bias drift of the electronics",
    ("bias", "orbit"): "a bias cycling over the orbit",
    ("bias", "time"): "bias drift (ageing, settling)",
    ("bias", "aux"): "a bias following",
    ("scale", "temperature"): "thermal gain drift",
    ("scale", "orbit"): "a gain cycling over the orbit",
    ("scale", "time"): "gain drift (ageing)",
    ("scale", "aux"): "a gain following",
    ("bias", "heater"): "bias step with the heater",
}

#: the unit a drifting effect's coefficient is spoken of in, by effect (a bias in the sensor's own unit)
_PARAM_UNIT = {"alignment": "arcsec", "scale": "ppm", "bias": "{unit}"}


def _kind(tag: str, base: str = "") -> str:
    if tag in ORBIT_TAGS:
        return "orbit"
    if tag == TIME_TAG:
        return "time"
    if base == "bias" and "heater" in tag.lower():
        return "heater"
    return "temperature" if "temp" in tag.lower() else "aux"


def family_name(effect: str, sensor_unit: str = "sensor units") -> str | None:
    """Physics and unit of a family effect, e.g. ``thermo-elastic bending, arcsec per °C``;
    None for a name that is not a family."""
    from gcs_core.diagnosis.channels import aux_unit

    parts = split_family(effect)
    if parts is None:
        return None
    base, tag = parts
    kind = _kind(tag, base)
    what = PHYSICS[(base, kind)]
    if kind == "aux":
        what += f" {tag}"
    shown = _PARAM_UNIT[base].format(unit="°/h" if sensor_unit == "rad/s" else sensor_unit)
    per = {"orbit": f"{shown} amplitude of the orbit's harmonic {ORBIT_TAGS.get(tag, '')}"}.get(kind)
    if per is None:
        per = f"{shown} per " + ("hour" if kind == "time" else aux_unit(tag))
    return f"{what}, {per}"


def explanation(effect: str) -> tuple[str, str] | None:
    """(family, explanation) of a family effect for the catalogue; None for other names."""
    parts = split_family(effect)
    if parts is None:
        return None
    base, tag = parts
    kind = _kind(tag, base)
    chan = {"orbit": f"the orbit phase ({'once' if tag == 'orbit1' else 'twice'} per orbit)", "time": "time"}.get(
        kind, f"'{tag}'"
    )
    if kind == "heater":
        return (
            "drift",
            f"bias step with the heater, the bias per unit of '{tag}' (°/h for a gyro): the bias steps when "
            f"'{tag}' switches. "
            f"On a gyro carrying the attitude the step turns the attitude by its time integral, and every "
            f"sensor's residual follows the integral of '{tag}' (a generic family made from the "
            "residual-structure search, carried inside the gyro-propagated attitude).",
        )
    return (
        "drift",
        f"{family_name(effect)}: the sensor's {base} is not constant but varies linearly with {chan}. "
        f"The residual follows {chan} through the {base}'s own signature (a generic family made from the "
        "residual-structure search, first order in the drift).",
    )


def offered_for(dep: Dependency, model, *, aliases: Iterable[str] = ()) -> list[str]:
    """Family effects of ``model`` (the sensor of ``dep``) that could explain ``dep``."""
    from gcs_core.models.drift import DriftingModel

    inner = model.inner if isinstance(model, DriftingModel) else model
    base = drifting_params(inner)
    tags: list[str] = []
    names = [dep.channel, *aliases]
    for ch in names:
        if ch in POSITION:  # a field following the position is the catalogue's field gradient
            continue
        if ch.startswith("aux:"):
            tags.append(ch[4:])
        elif ch in ("orbit_phase", "sun_angle", "eclipse"):
            tags += list(ORBIT_TAGS)
        elif ch == "time":
            tags.append(TIME_TAG)
    contaminated = set(getattr(inner, "contamination_channels", ()) or ())
    out = []
    for tag in dict.fromkeys(tags):
        for eff in DRIFTING:
            if eff not in base:
                continue
            if eff == "bias" and tag in contaminated:
                continue  # the catalogue's contamination_<tag> is that very family
            out.append(f"{eff}_vs_{tag}")
    return out


def families_from(
    found: Iterable[Dependency], models: Mapping[str, object], gyro: str | None = None
) -> dict[str, tuple[str, ...]]:
    """sensor -> the family effects to offer for the significant dependencies ``found``. A
    dependency on the time integral of a switched aux channel (``int:<name>``) in any
    sensor's residual, or the gyro's own (:mod:`gcs_core.diagnosis.gyro_search`), makes the
    gyro ``gyro`` (carrying the attitude) offer its bias following the switch,
    ``bias_vs_<name>`` (:mod:`gcs_core.models.gyro_steps`); nothing else of the gyro's."""
    out: dict[str, list[str]] = {}
    for d in found:
        if d.kind == "aux_integral" or (d.sensor == gyro and d.channel.startswith("aux:")):
            if gyro is not None:
                fam = f"bias_vs_{d.channel.split(':', 1)[1]}"
                lst = out.setdefault(gyro, [])
                if fam not in lst:
                    lst.append(fam)
            continue
        model = models.get(d.sensor)
        if model is None:
            continue
        aux_aliases = [a for a in d.aliases if a.startswith("aux:") or a == "orbit_phase"]
        for fam in offered_for(d, model, aliases=aux_aliases):
            lst = out.setdefault(d.sensor, [])
            if fam not in lst:
                lst.append(fam)
    return {k: tuple(v) for k, v in out.items()}


def channel_of(effect: str) -> str | None:
    """The search channel a family effect is made on (``aux:tam_temp``, ``orbit_phase``, ``time``)."""
    parts = split_family(effect)
    if parts is None:
        return None
    tag = parts[1]
    if tag in ORBIT_TAGS:
        return "orbit_phase"
    return "time" if tag == TIME_TAG else f"aux:{tag}"
