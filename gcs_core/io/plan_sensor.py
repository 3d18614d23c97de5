"""The ``[[sensor]]`` keys of a plan file only (docs/planning.md).

A plan (an analysis config with its own ``[mission]`` and ``[[sensor]]`` tables, read by
:func:`gcs_core.io.mission.read_mission_spec` with ``planning=True``) describes sensors
that have no telemetry yet: how often each delivers a frame, when it does not, and what a
magnetometer measures. Errors name the file, line and key as every mission.toml check does.
"""

from __future__ import annotations

from typing import Any

from gcs_core.io.toml_fields import Ctx, number, numbers, string

#: [[sensor]] keys of a plan file only (docs/planning.md): the frame spacing [s], the
#: sensor's own data gaps [[t0, t1], ...] [s since the epoch] and a magnetometer's
#: observable ("vector" or "magnitude", gcs_core.predictor.magnitude)
PLAN_SENSOR_KEYS = ("cadence", "gaps", "observable")


def plan_keys(ctx: Ctx, raw: dict, base: str, index: int) -> dict[str, Any]:
    """A plan's ``cadence`` (> 0 s) and ``gaps`` ([[t0, t1], ...] with t0 < t1) of one sensor."""
    out: dict[str, Any] = {}
    if "cadence" in raw:
        c = number(ctx, raw["cadence"], f"{base}.cadence", "sensor", index, "cadence")
        if not c > 0:
            raise ctx.error(f"must be > 0 s, not {c:g}", f"{base}.cadence", "sensor", index, "cadence")
        out["cadence"] = c
    if "observable" in raw:
        out["observable"] = string(ctx, raw["observable"], f"{base}.observable", "sensor", index, "observable")
        if out["observable"] not in ("vector", "magnitude") or raw.get("type") != "magnetometer":
            raise ctx.error(
                'a magnetometer\'s observable is "vector" or "magnitude"',
                f"{base}.observable",
                "sensor",
                index,
                "observable",
            )
    if "gaps" in raw:
        g = raw["gaps"]
        if not isinstance(g, list):
            raise ctx.error("must be a list of [t0, t1] pairs [s]", f"{base}.gaps", "sensor", index, "gaps")
        pairs = []
        for k, pair in enumerate(g, start=1):
            a, b = numbers(ctx, pair, 2, f"{base}.gaps[{k}]", "sensor", index, "gaps")
            if not a < b:
                raise ctx.error(f"needs t0 < t1, not [{a:g}, {b:g}]", f"{base}.gaps[{k}]", "sensor", index, "gaps")
            pairs.append((a, b))
        out["gaps"] = tuple(pairs)
    return out
