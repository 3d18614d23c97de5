"""Astro Pi flight data (a Sense HAT on the ISS) to a GCS mission directory.

Input: the Raspberry Pi Foundation's Astro Pi CSV (``Date/Time`` in UTC as
``YYYY-MM-DD HH:MM:SS``, ``MagX, MagY, MagZ`` in µT, and ``Temperature`` [°C],
``Humidity`` [%], ``Pressure`` [hPa], ``C`` (clear light) when present), and the
station's two-line elements (``tle``). Columns are found by name, in any order.

Output (ICD §1, with the ``[orbit] tle`` extension of :mod:`gcs_core.ephem.tle`)::

    mission.toml         earth_pointing mission, one magnetometer MAG
    orbit.tle            the elements, copied
    telemetry/MAG.csv    t [s], bx, by, bz [nT], flag (1: start-up transient, kept, unused)
    aux.csv              t, temperature_c, humidity_pct, pressure_hpa, light_clear
    LICENCE.md, SOURCE.md  copied from beside the source file when there
    PROVENANCE.md        what was read, converted, flagged and estimated

What the data book cannot know is estimated from the data and said so in mission.toml
and PROVENANCE.md:

- **noise**: white noise from second differences (:func:`gcs_core.noise.measured.white_noise`,
  which also removes the field's slope along the orbit, ≈ 0.1 µT per 5 s), the RMS over
  the three axes, marked :data:`gcs_core.noise.measured.ESTIMATED_MARK`;
- **the start-up transient**: the leading samples before the second differences settle and
  while they lie more than 3σ from the steady field extrapolated back
  (:func:`~gcs_core.convert.common.leading_transient`), written with ``flag = 1``;
- **the mounting** (``alignment_deg``) and a first **bias**: the rotation ``M`` and offset
  ``b`` minimizing ``Σ |B_S − M B_L − b|²``, ``B_L`` the IGRF field along the TLE orbit in
  the local-vertical/local-horizontal frame (``earth_pointing``, ICD §2). With both centred
  the rotation is the orthogonal Procrustes solution ``M = U diag(1, 1, det(UVᵀ)) Vᵀ`` of
  ``Σ (B_S − B̄_S)(B_L − B̄_L)ᵀ = U S Vᵀ``, and ``b = B̄_S − M B̄_L`` (Schönemann 1966).
  The station flies near LVLH; the small constant offset from it is the attitude
  (``att.roll/pitch/yaw``) the fit estimates.

References
----------
Raspberry Pi Foundation, "Astro Pi Flight Data Analysis",
github.com/raspberrypilearning/astro-pi-flight-data-analysis (CC BY-SA 4.0).
Schönemann, P. H., "A generalized solution of the orthogonal Procrustes problem",
Psychometrika 31(1), 1–10 (1966).
"""

from __future__ import annotations

import logging
import shutil
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from gcs_core.convert import ConversionReport
from gcs_core.convert.common import (
    NamedCsv,
    check_destination,
    check_source,
    leading_transient,
    read_named_csv,
    sha256,
    staged_directory,
    write_csv,
)
from gcs_core.errors import InputError
from gcs_core.noise.measured import ESTIMATED_MARK, white_noise

log = logging.getLogger(__name__)

__all__ = ["convert", "SENSOR", "procrustes_mounting"]

SENSOR = "MAG"
TIME_COLUMN = "Date/Time"
FIELD_COLUMNS = ("MagX", "MagY", "MagZ")
#: source column -> aux channel name (written when the source has the column)
AUX_COLUMNS = {"Temperature": "dtemp_c", "Humidity": "dhumidity_pct", "Pressure": "dpressure_hpa", "C": "light_clear"}
#: channels written as the deviation from their median over the file: a contamination
#: ``k (T − T_med)`` is then not 99.99 % a bias (T varies by 0.3 °C about 33.7 °C), so the
#: diagnosis can tell the two apart; light has a physical zero (dark) and stays as read
CENTRED = ("Temperature", "Humidity", "Pressure")
UT_TO_NT = 1000.0
_TIME_FORMAT = "%Y-%m-%d %H:%M:%S"


def _times(table) -> tuple[datetime, np.ndarray]:
    """UTC epoch (the first row) and seconds since it, strictly increasing."""
    stamps = []
    for k, text in enumerate(table.text(TIME_COLUMN)):
        try:
            stamps.append(datetime.strptime(text.strip(), _TIME_FORMAT).replace(tzinfo=UTC))
        except ValueError:
            raise table.error(k, TIME_COLUMN, f"{text.strip()!r} is not a UTC time 'YYYY-MM-DD HH:MM:SS'") from None
    epoch = stamps[0]
    t = np.array([(s - epoch).total_seconds() for s in stamps])
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        k = int(bad[0]) + 1
        raise table.error(
            k,
            TIME_COLUMN,
            f"time {stamps[k]:%Y-%m-%d %H:%M:%S} does not follow "
            f"{stamps[k - 1]:%Y-%m-%d %H:%M:%S} (line {table.lines[k - 1]})",
        )
    return epoch, t


def procrustes_mounting(B_S: np.ndarray, B_L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation ``M`` (3, 3) and offset ``b`` (3,) minimizing ``Σ |B_S − M B_L − b|²``
    (module docstring). ``B_S, B_L`` (N, 3) in the same unit."""
    mS, mL = B_S.mean(axis=0), B_L.mean(axis=0)
    H = (B_S - mS).T @ (B_L - mL)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    M = U @ D @ Vt
    return M, mS - M @ mL


#: largest field component accepted [nT] (the importer's bound: the Earth's is < 7e4 nT)
MAX_FIELD_NT = 1e6
#: largest magnitude of an aux reading accepted (temperature, humidity, pressure, light)
MAX_AUX = 1e9


def _refuse_absurd(table, B: np.ndarray, aux: dict[str, np.ndarray]) -> None:
    """Refuse a field beyond :data:`MAX_FIELD_NT` or an aux value beyond :data:`MAX_AUX`
    at its line and column (a 1e300 would otherwise overflow the estimates)."""
    bad = np.argwhere(np.abs(B) > MAX_FIELD_NT)
    if bad.size:
        k, j = (int(x) for x in bad[0])
        raise table.error(k, FIELD_COLUMNS[j], f"{B[k, j] / UT_TO_NT:g} µT exceeds ±{MAX_FIELD_NT / UT_TO_NT:g} µT")
    for column, name in AUX_COLUMNS.items():
        if name in aux and np.any(np.abs(aux[name]) > MAX_AUX):
            k = int(np.argmax(np.abs(aux[name]) > MAX_AUX))
            raise table.error(k, column, f"{aux[name][k]:g} exceeds ±{MAX_AUX:g}")


def _lvlh_field(tle_file: Path, epoch: datetime, t: np.ndarray) -> tuple[np.ndarray, str]:
    """IGRF [nT] along the TLE orbit in the earth_pointing (LVLH) frame, (N, 3), and a
    warning ('' if none) when the data lie more than ``STALE_DAYS`` from the elements' epoch."""
    from gcs_core.ephem import timescale
    from gcs_core.ephem.geomag import GeomagField
    from gcs_core.ephem.orbit import TleOrbit
    from gcs_core.ephem.tle import STALE_DAYS, read_tle, tle_states
    from gcs_core.frames.reference import reference_dcm

    orbit = TleOrbit(*read_tle(tle_file), epoch)
    jd = timescale.julian_date(epoch, np.array([float(t[0]), float(t[-1])]))
    far = float(np.max(np.abs(jd - orbit.tle_epoch_jd)))
    warning = ""
    if far > STALE_DAYS:
        warning = (
            f"the data lie {far:.1f} days from the epoch of {tle_file.name} (SGP4's error grows by "
            "1-3 km a day in low orbit): use elements of the data's days"
        )
        log.warning("%s", warning)
        warning = "warning: " + warning
    r, v, _ = tle_states(orbit, epoch, t, "teme")
    B_I = GeomagField(epoch).field_I(t, r)
    return np.einsum("nij,nj->ni", reference_dcm("earth_pointing", r, v), B_I), warning


@dataclass(frozen=True)
class _Readings:
    """What the Astro Pi CSV holds, converted: the table read, the epoch (its first row) and
    seconds since it, the field [nT], the aux channels (centred ones minus their median)."""

    table: NamedCsv
    epoch: datetime
    t: np.ndarray
    B: np.ndarray
    aux: dict[str, np.ndarray]
    medians: dict[str, float]

    @property
    def median_text(self) -> str:
        return ", ".join(f"{c} {m:g}" for c, m in self.medians.items())


@dataclass(frozen=True)
class _Estimates:
    """What the data book cannot know, estimated from the data (module docstring): the white
    noise per axis and its RMS [nT], the start-up transient's length and each row's flag, the
    mounting [deg] and bias [nT] with the RMS they leave [nT], and the TLE's staleness
    warning ('' if none)."""

    sigma: np.ndarray
    noise: float
    n_transient: int
    flag: np.ndarray
    align_deg: np.ndarray
    bias: np.ndarray
    rigid_rms: float
    tle_warning: str


def _mission_toml(name: str, r: _Readings, e: _Estimates) -> str:
    a = ", ".join(f"{x:.3f}" for x in e.align_deg)
    b = ", ".join(f"{x:.1f}" for x in e.bias)
    s = ", ".join(f"{x:.1f}" for x in e.sigma)
    text = f"""# Converted by `gcs convert astropi` from the Raspberry Pi Foundation's Astro Pi flight data
# (CC BY-SA 4.0, see LICENCE.md, SOURCE.md and PROVENANCE.md): the unit's magnetometer inside the ISS.
[mission]
name = "{name}"
epoch = "{r.epoch:%Y-%m-%dT%H:%M:%SZ}"        # the first sample
attitude_mode = "earth_pointing"            # the station flies near local-vertical/local-horizontal

[orbit]                                     # no ephemeris file: SGP4 from the station's elements
tle = "orbit.tle"
frame = "teme"                              # the ICD's GCI (gcs_core/ephem/teme.py)
step_s = 10.0

[aux]
file = "aux.csv"

[[sensor]]
name = "{SENSOR}"
type = "magnetometer"
telemetry = "telemetry/{SENSOR}.csv"        # {e.n_transient} start-up samples flagged (flag = 1), kept, not used
# ESTIMATED, not a data book: the mounting is unknown. Rotation and offset fitted against IGRF
# along the TLE orbit in LVLH (orthogonal Procrustes), leaving {e.rigid_rms:.0f} nT RMS.
alignment_deg = [{a}]
bias = [{b}]                                # nT
# {ESTIMATED_MARK} (second differences; per axis [{s}] nT): the white noise it shows.
noise = {e.noise:.1f}                      # nT
"""
    return text if r.aux else text.replace('[aux]\nfile = "aux.csv"\n\n', "")


def _provenance(source: Path, tle: Path, r: _Readings, e: _Estimates) -> str:
    return f"""# Provenance

Converted by `gcs convert astropi` (gcs_core/convert/astropi.py).

- Source: `{source.name}` ({len(r.table)} data rows), SHA-256 `{sha256(source)}`.
- Orbit: `{tle.name}` copied as `orbit.tle` (SHA-256 `{sha256(tle)}`); GCS propagates it
  with SGP4 (the `[orbit]` extension, docs/icd_extensions.md).
- Time: `Date/Time` read as UTC; `t` = seconds since {r.epoch:%Y-%m-%dT%H:%M:%SZ}, the first row.
- Magnetometer `MagX, MagY, MagZ` [µT] × 1000 → `telemetry/{SENSOR}.csv` `bx, by, bz` [nT], every
  row kept. The first {e.n_transient} rows are the unit's start-up transient (the field settling
  from zero, then more than 3σ off the steady field extrapolated back; `leading_transient` in
  gcs_core/convert/common.py) and carry `flag = 1`: kept in the file, not used.
- Auxiliary channels → `aux.csv`: {", ".join(r.aux) or "none"}; `dtemp_c`,
  `dhumidity_pct`, `dpressure_hpa` are `Temperature` [°C], `Humidity` [%], `Pressure` [hPa]
  minus their median over the file ({r.median_text}), so that a contamination by them is not
  almost all a bias; `light_clear` is the `C` (clear) light channel as read.
- Not converted: `Latitude, Longitude` (written onboard from an orbit known to be several
  minutes of track off: the position comes from the TLE), `Compass, Pitch, Roll, Yaw` (the
  HAT's own fusion), `AccelX..Z` (zero), `R, G, B` (light), `Motion`.

## Estimated from the data (not a data book)

- White noise per axis {", ".join(f"{x:.1f}" for x in e.sigma)} nT (second differences of
  consecutive samples, 5σ-clipped, / √6); `noise = {e.noise:.1f}` nT is their RMS. The file
  writes 0.1 µT steps: quantization alone is 29 nT.
- Mounting `alignment_deg = [{", ".join(f"{x:.3f}" for x in e.align_deg)}]` and bias
  `[{", ".join(f"{x:.0f}" for x in e.bias)}]` nT: the rotation and offset that best map IGRF along
  the TLE orbit in LVLH onto the measurements (orthogonal Procrustes); {e.rigid_rms:.0f} nT RMS left.

## Licence

The data are © Raspberry Pi Foundation, CC BY-SA 4.0 (LICENCE.md); this mission directory is
derived from them and is distributed under the same licence, with that attribution.
"""


def _read(source: Path) -> _Readings:
    """The CSV's times, field and aux channels, every value checked (module docstring)."""
    table = read_named_csv(source, (TIME_COLUMN, *FIELD_COLUMNS))
    epoch, t = _times(table)
    B = np.column_stack([table.numbers(c) for c in FIELD_COLUMNS]) * UT_TO_NT
    aux = {AUX_COLUMNS[c]: table.numbers(c) for c in AUX_COLUMNS if c in table.header}
    _refuse_absurd(table, B, aux)
    medians = {}
    for c in CENTRED:
        if AUX_COLUMNS[c] in aux:
            medians[c] = float(np.median(aux[AUX_COLUMNS[c]]))
            aux[AUX_COLUMNS[c]] = aux[AUX_COLUMNS[c]] - medians[c]
    return _Readings(table, epoch, t, B, aux, medians)


def _estimate(r: _Readings, tle: Path) -> _Estimates:
    """The noise, the start-up transient and the mounting, from the data (module docstring)."""
    from gcs_core.frames.rotations import dcm_to_euler123

    t, B = r.t, r.B
    # white noise from the data (gcs_core.noise.measured, the one estimator of both converters);
    # measured again without the start-up transient it helped to find
    sigma = white_noise(t, B)
    n_tr = leading_transient(B, sigma, t=t)
    sigma = white_noise(t[n_tr:], B[n_tr:])
    noise = float(np.sqrt(np.mean(sigma**2)))
    flag = np.zeros(t.size, dtype=int)
    flag[:n_tr] = 1

    use = flag == 0
    B_L, tle_warning = _lvlh_field(tle, r.epoch, t)
    M, bias = procrustes_mounting(B[use], B_L[use])
    rigid_rms = float(np.sqrt(np.mean(np.sum((B[use] - B_L[use] @ M.T - bias) ** 2, axis=1) / 3)))
    align = np.degrees(np.array(dcm_to_euler123(M), dtype=float))
    return _Estimates(sigma, noise, n_tr, flag, align, bias, rigid_rms, tle_warning)


def _write(stage: Path, source: Path, tle: Path, name: str, r: _Readings, e: _Estimates) -> list[str]:
    """The mission directory's files, in ``stage``; returns the files written."""
    (stage / "telemetry").mkdir()
    write_csv(
        stage / "telemetry" / f"{SENSOR}.csv",
        ("t", "bx", "by", "bz", "flag"),
        (r.t, *r.B.T, e.flag),
        ("%.3f", "%.1f", "%.1f", "%.1f", "%d"),
        comments=(
            "Astro Pi Mark II magnetometer on the ISS, nT (source µT x 1000); "
            "flag 1 = start-up transient, kept, not used",
            "Data: Raspberry Pi Foundation, CC BY-SA 4.0 (LICENCE.md)",
        ),
    )
    files = ["mission.toml", "orbit.tle", f"telemetry/{SENSOR}.csv"]
    if r.aux:
        write_csv(
            stage / "aux.csv",
            ("t", *r.aux),
            (r.t, *r.aux.values()),
            ("%.3f",) + ("%.6g",) * len(r.aux),
            comments=(
                "Astro Pi channels beside the magnetometer (PROVENANCE.md); d* = deviation from the median: "
                + r.median_text,
            ),
        )
        files.append("aux.csv")
    shutil.copyfile(tle, stage / "orbit.tle")
    (stage / "mission.toml").write_text(_mission_toml(name, r, e), encoding="utf-8")
    for extra in ("LICENCE.md", "LICENSE.md", "LICENSE", "SOURCE.md"):
        if (source.parent / extra).is_file():
            shutil.copyfile(source.parent / extra, stage / extra)
            files.append(extra)
    (stage / "PROVENANCE.md").write_text(_provenance(source, tle, r, e), encoding="utf-8")
    files.append("PROVENANCE.md")
    return files


def _report(source: Path, out: Path, files: list[str], r: _Readings, e: _Estimates) -> ConversionReport:
    notes = (
        f"MagX..Z µT -> bx..bz nT; epoch {r.epoch:%Y-%m-%dT%H:%M:%SZ} (first row)",
        f"start-up transient: first {e.n_transient} samples flagged (flag = 1), kept",
        f"noise estimated from the data: {e.noise:.1f} nT (per axis " + ", ".join(f"{x:.1f}" for x in e.sigma) + ")",
        "mounting estimated against IGRF in LVLH: alignment_deg ["
        + ", ".join(f"{x:.2f}" for x in e.align_deg)
        + f"], {e.rigid_rms:.0f} nT RMS left",
    ) + ((e.tle_warning,) if e.tle_warning else ())
    return ConversionReport(
        format="astropi",
        source=source,
        out=out,
        rows=len(r.table),
        samples={SENSOR: int(r.t.size), "aux": int(r.t.size) if r.aux else 0},
        flagged={SENSOR: e.n_transient},
        files=tuple(files),
        notes=notes,
    )


def convert(
    source: Path, out: Path, *, tle: str | Path | None = None, overwrite: bool = False, name: str | None = None
) -> ConversionReport:
    """Convert an Astro Pi CSV and the station's TLE into the mission directory ``out``.

    Parameters
    ----------
    source : the Astro Pi CSV file.
    out : the mission directory to create (refused when non-empty unless ``overwrite``).
    tle : the two-line element file of the station (required).
    name : mission name (default: the output directory's name).
    """
    from gcs_core.ephem.tle import read_tle

    source, out = Path(source), Path(out)
    if tle is None:
        raise InputError("the Astro Pi converter needs the station's two-line elements (--tle FILE)", key="tle")
    tle = Path(tle)
    check_source(source, "astropi")
    check_destination(source, out, overwrite=overwrite)  # before the work: fail fast
    read_tle(tle)
    readings = _read(source)
    estimates = _estimate(readings, tle)
    with staged_directory(out, overwrite=overwrite, source=source) as stage:
        files = _write(stage, source, tle, name or out.name, readings, estimates)
    return _report(source, out, files, readings, estimates)
