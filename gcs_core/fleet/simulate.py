"""A simulated fleet: N spacecraft on varied orbits and modes, consecutive days, with hidden
effects in some, a calibration that moves in others and malformed files in a few.

Every mission is made by the project's simulator (:mod:`gcs_core.sim`), so the truth is
known and independent of the estimator. Spacecraft ``i`` (0-based) of ``n``:

* mode ``sun_pointing``, ``inertial`` or ``earth_pointing`` in turn; orbit semi-major axis
  6778 to 7128 km, inclination 28.5°, 51.6°, 97.5° or 65°, node and phase spread;
* ``i % 5 == 1``: a hidden effect the data book does not have (TAM1 contamination by the
  x torquer, :data:`EFFECT`), every day: discovery should name it;
* ``i % 5 == 2``: the TAM1 bias moves by :data:`MOVE_NT` from the second day on: the fleet
  report should name ``TAM1.bias_*`` as moved;
* ``i % 7 == 3``: on day ``i % days`` the TAM1 telemetry holds a malformed field (line
  :data:`MALFORMED_LINE`, column ``bx``): that spacecraft-day's one-line error;
* odd ``i``: the onboard attitude is off by a few hundredths of a degree (§4.4 flag at the
  template's 0.01° requirement); even ``i``: exact up to 2″ noise.

:func:`simulate_fleet` writes ``data/<SC>/<day>/`` mission directories, ``fleet.toml``
(the manifest) and ``truth.json`` (what was injected, outside the data).
"""

from __future__ import annotations

import json
from datetime import datetime, timedelta
from pathlib import Path

from gcs_core.fleet.manifest import read_manifest

__all__ = ["simulate_fleet", "EFFECT", "MOVE_NT", "MALFORMED_LINE", "MODES"]

MODES = ("sun_pointing", "inertial", "earth_pointing")
INCLINATIONS_DEG = (28.5, 51.6, 97.5, 65.0)
#: the hidden effect injected into every fifth spacecraft: (effect id, magnitude [nT/(A m²)])
EFFECT = ("TAM1.contamination_mtb_x", 3.0)
#: how far the TAM1 bias moves from the second day on [nT]
MOVE_NT = 150.0
#: the line of TAM1.csv made malformed (1-based, the header is line 1)
MALFORMED_LINE = 50
EPOCH0 = datetime(2024, 5, 14, 4, 0, 0)


def _mission(i: int, day: int, duration_s: float, seed: int):
    from gcs_core.sim.config import OnboardConfig, OrbitElements
    from gcs_core.sim.scenarios import nominal_threeaxis, with_effect

    orbit = OrbitElements(
        a_km=6778.137 + 50.0 * (i % 8),
        e=0.001,
        i_deg=INCLINATIONS_DEG[i % len(INCLINATIONS_DEG)],
        raan_deg=(37.0 * i) % 360.0,
        argp_deg=60.0,
        mean_anomaly_deg=(53.0 * i) % 360.0,
    )
    epoch = (EPOCH0 + timedelta(days=day)).strftime("%Y-%m-%dT%H:%M:%SZ")
    cfg = nominal_threeaxis(
        MODES[i % len(MODES)],
        seed=seed * 100003 + 101 * i + day,
        duration_s=duration_s,
        name=f"SC{i + 1:02d}",
        epoch=epoch,
        orbit=orbit,
    )
    err = (0.03, -0.04, 0.0) if i % 2 else (0.0, 0.0, 0.0)
    cfg.onboard = OnboardConfig(cadence_s=10.0, error_deg=err, noise_arcsec=2.0)
    injected: list[dict] = []
    if i % 5 == 1:
        cfg = with_effect(cfg, EFFECT[0], EFFECT[1])
        injected.append({"effect": EFFECT[0], "magnitude": EFFECT[1]})
    if i % 5 == 2 and day >= 1:
        cfg = with_effect(cfg, "TAM1.bias", MOVE_NT)
        injected.append({"effect": "TAM1.bias", "magnitude": MOVE_NT, "moved": True})
    return cfg, injected


def _malform(path: Path, line: int) -> None:
    """Replace the ``bx`` field of ``line`` of a TAM telemetry file by a non-number."""
    lines = path.read_text().splitlines(keepends=True)
    cols = lines[line - 1].split(",")
    cols[1] = "12..5x"
    lines[line - 1] = ",".join(cols)
    path.write_text("".join(lines))


MANIFEST = """# A simulated fleet (gcs_core.fleet.simulate); the answers are in truth.json.
[fleet]
name = "{name}"
days = [{days}]
output = "out"
discover = {discover}
max_steps = 2
moved_sigma = 5.0
outlier_sigma = 5.0

[template.analysis]
method = "{method}"

[template.diagnosis]
holdout_fraction = {holdout}

[template.verification]
requirement_deg = 0.01
"""


def simulate_fleet(
    root: str | Path,
    n: int = 4,
    days: int = 2,
    *,
    duration_s: float = 1200.0,
    seed: int = 1,
    discover: bool = True,
    method: str = "whole_span",
    holdout: float = 0.25,
    name: str = "simulated-fleet",
) -> Path:
    """Write a simulated fleet under ``root`` (module docstring); return the manifest path."""
    from gcs_core.sim.writer import write_mission

    root = Path(root)
    day_names = [f"day{d + 1}" for d in range(days)]
    truth: dict = {"spacecraft": {}, "effect": EFFECT[0], "moved_nt": MOVE_NT}
    lines = [
        MANIFEST.format(
            name=name,
            days=", ".join(f'"{d}"' for d in day_names),
            discover="true" if discover else "false",
            method=method,
            holdout=holdout,
        )
    ]
    for i in range(n):
        sc = f"SC{i + 1:02d}"
        rec: dict = {"mode": MODES[i % len(MODES)], "days": {}}
        for d, day in enumerate(day_names):
            cfg, injected = _mission(i, d, duration_s, seed)
            out = write_mission(cfg, root / "data" / sc / day)
            malformed = None
            if i % 7 == 3 and d == i % days:
                path = out / "telemetry" / "TAM1.csv"
                _malform(path, MALFORMED_LINE)
                malformed = {"file": str(path.relative_to(root)), "line": MALFORMED_LINE, "column": "bx"}
            rec["days"][day] = {"injected": injected, "malformed": malformed, "onboard_error": i % 2 == 1}
        truth["spacecraft"][sc] = rec
        lines.append(f'[[spacecraft]]\nname = "{sc}"\ndata = "data/{sc}/{{day}}"\n')
    manifest = root / "fleet.toml"
    manifest.write_text("\n".join(lines))
    (root / "truth.json").write_text(json.dumps(truth, indent=2))
    read_manifest(manifest)  # the simulator writes only what the reader takes
    return manifest
