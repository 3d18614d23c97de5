"""The text files ``gcs convert broad`` writes into a mission: ``mission.toml`` (the data
book, every noise figure marked as estimated) and ``SOURCE.md`` (provenance and licence),
for :mod:`gcs_core.convert.broad`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gcs_core.convert.broad_noise import Noise, rms
from gcs_core.convert.holds import FLAG_HELD, FLAG_INTERPOLATED
from gcs_core.noise import measured as noise_mod

if TYPE_CHECKING:
    from gcs_core.convert.broad import Notes, Trial


@dataclass(frozen=True)
class Site:
    """Where and what the data are: the citation, the epoch that labels the times, the
    Earth's centre seen from the laboratory [km, ENU] and its latitude [deg N]
    (:mod:`gcs_core.convert.broad`'s constants)."""

    citation: str
    epoch: str
    position_km: tuple[float, float, float]
    latitude_deg: float


def mission_toml(name: str, source: Path, noise: Noise, n_held: tuple[int, int], site: Site) -> str:
    """The mission.toml text: the data book of ``noise`` and the ``n_held`` (held repeats,
    interpolated samples) of the magnetometer."""
    CITATION, EPOCH, LAB_POSITION_KM, LAB_LATITUDE_DEG = site.citation, site.epoch, site.position_km, site.latitude_deg
    bias0, arw, rrw, n_rest = noise.bias0, noise.arw, noise.rrw, noise.n_rest
    m_line, o_line, s_mag, s_opt, s_gyr = noise.m_line, noise.o_line, noise.s_mag, noise.s_opt, noise.s_gyr
    b = ", ".join(f"{v:.6g}" for v in bias0)
    return f"""# Converted by `gcs convert broad` from {source.name}, a trial of BROAD:
# {CITATION}
# Provenance, licence and the conversion notes: SOURCE.md, LICENSE, conversion.json.
# A ground mission (docs/ground.md): analyse it with field_model = "constant".
[mission]
name = "{name}"
epoch = "{EPOCH}"   # the recording date is not published: the epoch only labels t
attitude_mode = "inertial"        # the laboratory's East-North-Up frame stands for GCI

[aux]
file = "aux.csv"                  # pos_x, pos_y, pos_z [m, ENU]: the optical position from the file's mean

[ephemeris]
ground_position_km = [{LAB_POSITION_KM[0]:.1f}, {LAB_POSITION_KM[1]:.1f}, {LAB_POSITION_KM[2]:.1f}]   # the Earth's centre, straight down (ENU)
latitude_deg = {LAB_LATITUDE_DEG}               # Berlin (the paper names TU Berlin, not the room): the Earth's rate in ENU

[[sensor]]
name = "GYR"                      # myon aktos-t gyro
type = "gyro"
telemetry = "telemetry/GYR.csv"
alignment_deg = [0.0, 0.0, 0.0]
bias = [{b}]   # rad/s, measured: mean over {int(n_rest)} samples at rest (the middle half of the longest rest)
arw = {arw:.6g}   # rad/s^0.5, {noise_mod.ESTIMATED_MARK}: Allan deviation at rest, -1/2 line (per-sample spread {np.array2string(s_gyr, precision=4)} rad/s)
rrw = {rrw:.6g}   # rad/s^1.5, {noise_mod.ESTIMATED_MARK}: Allan deviation at rest, +1/2 line (an upper bound where it never shows)

[[sensor]]
name = "MAG"                      # myon aktos-t magnetometer (converted from µT)
type = "magnetometer"
telemetry = "telemetry/MAG.csv"   # flagged, kept, not used: {n_held[0]} held repeats (flag = {FLAG_HELD}), {n_held[1]} interpolated (flag = {FLAG_INTERPOLATED})
alignment_deg = [0.0, 0.0, 0.0]
noise = {rms(m_line):.6g}   # nT per sample used, {noise_mod.ESTIMATED_MARK}: white-noise line of the Allan deviation at rest of the samples used (per axis {np.array2string(m_line, precision=1)}; per-sample spread {np.array2string(s_mag, precision=1)})
bias = [0.0, 0.0, 0.0]

[[sensor]]
name = "OPT"                      # OptiTrack motion capture, eight Flex13 cameras
type = "attitude_reference"
telemetry = "telemetry/OPT.csv"
alignment_deg = [0.0, 0.0, 0.0]   # aligned to the unit by the data's authors
noise = {rms(o_line):.6g}   # rad, {noise_mod.ESTIMATED_MARK}: white-noise line of the Allan deviation at rest (per axis {np.array2string(o_line, precision=7)}; per-sample spread {np.array2string(s_opt, precision=7)})
"""  # noqa: E501 — the written file's own lines


def source_md(source: Path, trial: Trial, log: Notes, site: Site) -> str:
    """The SOURCE.md text (provenance, licence, what was flagged)."""
    CITATION, LAB_LATITUDE_DEG = site.citation, site.latitude_deg
    info, rate, n_all, span, keep = trial.info, trial.rate, trial.n_all, trial.span, trial.keep
    transients, warnings, holds = log.transients, log.warnings, log.holds
    lines = [
        f"# {source.name}",
        "",
        "Converted by `gcs convert broad` (gcs_core/convert/broad.py) from a trial of BROAD,",
        "the Berlin Robust Orientation Estimation Assessment Dataset.",
        "",
        f"Source: {CITATION}.",
        "",
        "Licence: Creative Commons Attribution 4.0 International (LICENSE). This mission is",
        "derived from the data: the units were converted (magnetometer µT to nT), the optical",
        "quaternion was reordered to scalar-last (x, y, z, w), and times were formed as",
        f"sample index / {rate:.6f} Hz. Nothing else was changed; every sample of the file is",
        "kept" + (" within the span below." if span else "."),
        "",
        f"Samples in the file: {n_all}; written: {int(keep.sum())}.",
    ]
    if span:
        lines.append(f"Span kept: t = {span[0]:g} to {span[1]:g} s from the file's first sample.")
    lines += [
        "",
        f"Laboratory latitude: {LAB_LATITUDE_DEG}° N, Berlin's (`[ephemeris] latitude_deg`, the Earth's",
        "rate seen by the gyro). The paper gives the authors' institute (Control Systems Group,",
        "TU Berlin, 10623 Berlin), not where the room is; the campus latitude stands for it.",
    ]
    lines += ["", "Flagged (kept):"] + [f"- {t}" for t in transients or ["no start-up transient found"]]
    lines += [
        "",
        "Samples not measured at their time stamp (a `flag` column: 2 a held repeat, 3 interpolated; kept, not used):",
    ]
    lines += [f"- {h}" for h in holds]
    lines += ["", "Warnings:"] + [f"- {w}" for w in warnings or ["none"]]
    lines += ["", "The file's own description:", "", "```", info.strip(), "```", ""]
    return "\n".join(lines)
