"""The ``[orbit]`` table of mission.toml: two-line elements instead of an ephemeris file.

An extension of ICD §3 (``docs/icd_extensions.md``); the orbit itself is built by
:mod:`gcs_core.ephem.tle`. Errors name mission.toml, the line and the key, as every
mission.toml check does (:mod:`gcs_core.io.mission`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from gcs_core.io.toml_fields import Ctx, existing_file, number, numbers, optional_file, string
from gcs_core.units import OMEGA_EARTH

__all__ = ["ORBIT_KEYS", "ORBIT_FRAMES", "GROUND_KEYS", "earth_rate", "ephemeris_or_orbit", "read_orbit_table"]

#: keys of [orbit]
ORBIT_KEYS = ("tle", "frame", "step_s")
#: keys of [ephemeris] on a ground mission (docs/ground.md)
GROUND_KEYS = ("ground_position_km", "latitude_deg", "earth_rate_rad_s")
#: a stated Earth rate vector must have this magnitude within this fraction (a unit check)
EARTH_RATE_TOLERANCE = 0.01
#: frames the orbit can be given in (gcs_core.ephem.teme.ORBIT_FRAMES)
ORBIT_FRAMES = ("teme", "j2000")


def read_orbit_table(ctx: Ctx, root: Path, t: Any, unknown: list[str]) -> tuple[Path, str, float]:
    """``[orbit]``: ``tle`` (file), optional ``frame`` and ``step_s`` (gcs_core.ephem.tle)."""
    if not isinstance(t, dict):
        raise ctx.error("[orbit] must be a table with a 'tle' key", "orbit", "orbit")
    if "tle" not in t:
        raise ctx.error("missing key 'tle' in [orbit] (the two-line element file)", "orbit.tle", "orbit")
    tle = existing_file(ctx, root, t["tle"], "orbit.tle", "orbit", "two-line element", tkey="tle")
    frame = string(ctx, t.get("frame", "teme"), "orbit.frame", "orbit", 1, "frame")
    if frame not in ORBIT_FRAMES:
        raise ctx.error(f"must be one of {', '.join(ORBIT_FRAMES)}, not {frame!r}", "orbit.frame", "orbit", 1, "frame")
    step = 10.0
    if "step_s" in t:
        step = number(ctx, t["step_s"], "orbit.step_s", "orbit", 1, "step_s")
        if not 0.0 < step <= 60.0:
            raise ctx.error(f"must be in (0, 60] s (ICD §4), not {step:g}", "orbit.step_s", "orbit", 1, "step_s")
    unknown += [f"orbit.{k}" for k in t if k not in ORBIT_KEYS]
    return tle, frame, step


def ephemeris_or_orbit(ctx: Ctx, root: Path, doc: dict, unknown: list[str]) -> tuple[Path | None, dict[str, Any]]:
    """``[ephemeris] file`` or ``[orbit]`` (one of them): the ephemeris path (None for an
    orbit) and the MissionSpec fields of the orbit (empty for an ephemeris file)."""
    e = doc.get("ephemeris")
    if "orbit" in doc:
        if e is not None:
            raise ctx.error(
                "give either [ephemeris] (a file) or [orbit] (two-line elements), not both", "orbit", "orbit"
            )
        tle, frame, step = read_orbit_table(ctx, root, doc["orbit"], unknown)
        return None, {"orbit_tle": tle, "orbit_frame": frame, "orbit_step_s": step}
    if not isinstance(e, dict) or "file" not in e:
        raise ctx.error(
            "missing [ephemeris] table with its 'file' key (ICD §3), or an "
            "[orbit] table with 'tle', or 'ground_position_km' for a ground mission",
            "ephemeris.file",
            "ephemeris",
        )
    return optional_file(ctx, root, doc, "ephemeris", unknown), {}


def ground_position(ctx: Ctx, e: dict, mode: str, unknown: list[str]) -> tuple[float, float, float]:
    """``[ephemeris] ground_position_km = [x, y, z]``: a laboratory on the ground
    (docs/ground.md). The reference frame is the laboratory's own (it stands where GCI
    stands in flight), so the mission must be ``inertial``."""
    pos = numbers(ctx, e["ground_position_km"], 3, "ephemeris.ground_position_km", "ephemeris", 1, "ground_position_km")
    norm = math.sqrt(sum(v * v for v in pos))
    if not 6300.0 <= norm <= 6400.0:
        raise ctx.error(
            f"|position| = {norm:.6g} km is not on the Earth's surface (6300 to 6400 km; position in km?)",
            "ephemeris.ground_position_km",
            "ephemeris",
            1,
            "ground_position_km",
        )
    if mode != "inertial":
        raise ctx.error(
            f"a ground mission (ground_position_km) needs attitude_mode = "
            f'"inertial" (the laboratory frame), not {mode!r}',
            "mission.attitude_mode",
            "mission",
            1,
            "attitude_mode",
        )
    unknown += [f"ephemeris.{k}" for k in e if k not in GROUND_KEYS]
    return pos[0], pos[1], pos[2]


def earth_rate(ctx: Ctx, e: dict) -> tuple[float, float, float] | None:
    """The Earth's rotation in the laboratory frame [rad/s] of a ground mission, or None.

    ``[ephemeris] latitude_deg = φ`` for a lab frame that is East-North-Up at geodetic
    latitude φ: ``ω_E^lab = Ω (0, cos φ, sin φ)``; or ``earth_rate_rad_s = [x, y, z]`` for
    any other lab frame (its magnitude must be Ω within 1 %), Ω = :data:`gcs_core.units.OMEGA_EARTH`
    (7.292115e-5 rad/s, the WGS 84 value). Not both. Absent: None (the
    Earth's rotation is left in the gyro's bias, docs/ground.md).
    """
    if "latitude_deg" in e and "earth_rate_rad_s" in e:
        raise ctx.error(
            "give either latitude_deg (an East-North-Up lab) or earth_rate_rad_s, not both",
            "ephemeris.earth_rate_rad_s",
            "ephemeris",
            1,
            "earth_rate_rad_s",
        )
    if "latitude_deg" in e:
        lat = number(ctx, e["latitude_deg"], "ephemeris.latitude_deg", "ephemeris", 1, "latitude_deg")
        if not -90.0 <= lat <= 90.0:
            raise ctx.error(
                f"latitude must be in [-90, 90] deg, not {lat:g}",
                "ephemeris.latitude_deg",
                "ephemeris",
                1,
                "latitude_deg",
            )
        phi = math.radians(lat)
        return 0.0, OMEGA_EARTH * math.cos(phi), OMEGA_EARTH * math.sin(phi)
    if "earth_rate_rad_s" in e:
        w = numbers(ctx, e["earth_rate_rad_s"], 3, "ephemeris.earth_rate_rad_s", "ephemeris", 1, "earth_rate_rad_s")
        norm = math.sqrt(sum(v * v for v in w))
        if abs(norm / OMEGA_EARTH - 1.0) > EARTH_RATE_TOLERANCE:
            raise ctx.error(
                f"|earth_rate_rad_s| = {norm:.6g} rad/s is not the Earth's rate "
                f"{OMEGA_EARTH:.8g} rad/s within 1 % (rad/s, in the lab frame?)",
                "ephemeris.earth_rate_rad_s",
                "ephemeris",
                1,
                "earth_rate_rad_s",
            )
        return w[0], w[1], w[2]
    return None
