"""BROAD trials (HDF5) to a GCS ground mission: ``gcs convert broad FILE.hdf5 --out DIR``.

BROAD, the Berlin Robust Orientation Estimation Assessment Dataset (Laidig, Caruso,
Cereatti, Seel, Data 6(7), 2021, doi:10.3390/data6070072; CC BY 4.0), records an inertial
unit moved by hand in a laboratory together with an optical motion-capture attitude.
One trial file holds, read here by name:

==============  ===========  ======================================================
dataset         shape        content
==============  ===========  ======================================================
``imu_gyr``     (N, 3)       gyro [rad/s]
``imu_acc``     (N, 3)       accelerometer [m/s²] (no GCS sensor: kept in extra/)
``imu_mag``     (N, 3)       magnetometer [µT] (written in nT, ×1000)
``opt_quat``    (N, 4)       unit quaternion (w, x, y, z) of the unit against the
                             laboratory's East-North-Up frame; NaN while untracked
``opt_pos``     (N, 3)       marker position [m] in ENU (kept in extra/; aux.csv)
``movement``    (N,)         bool, the motion phase
@sampling_rate  scalar       [Hz]
==============  ===========  ======================================================

The mission (docs/ground.md) is a ground mission: ``attitude_mode = "inertial"`` with the
laboratory's ENU frame standing where GCI stands in flight, ``ground_position_km`` the
Earth's centre seen from the laboratory (straight down), and the analysis config sets
``field_model = "constant"``. The laboratory's latitude (:data:`LAB_LATITUDE_DEG`, Berlin:
the paper names the institute, not the room) is written as ``latitude_deg``, so the
Earth's rotation is removed from the gyro exactly rather than left in its bias. The ENU
frame of the optical system is aligned by the data's authors; if its north is the local
magnetic north rather than the true, the Earth's rate is turned by the declination (about
4–5° E in Berlin, 2020), an error ≤ 5e-6 rad/s (docs/ground.md). It probably is: the
fitted field of trial 02 has no East component (−0.11 ± 0.04 of 15.1 µT north), so the
frame's north is the room's magnetic north within 0.5°: an error of about 3.5e-6 rad/s
(0.7 deg/h), a twentieth of the gyro bias σ a trial reaches. The optical
quaternion becomes an ``attitude_reference`` sensor: BROAD's ``(w, x, y, z)`` rotates
unit-frame vectors into ENU, which is GCS's ``C_BI`` of the scalar-last quaternion
``(x, y, z, w)`` (Eq 4-8) unchanged. The optical position becomes the aux channels
``pos_x, pos_y, pos_z`` [m, ENU] of ``aux.csv``, measured
from the mean tracked position of the whole file (the same point for any span of it), the
lever of the magnetometer's ``field_gradient`` effect (:mod:`gcs_core.models.magnetometer`);
untracked samples are left out of it (the channel holds the last tracked position).

Noise figures are not published with the data; each sensor's is estimated from its own
telemetry (:mod:`gcs_core.noise.measured`) and written with a comment saying so. The gyro's
data-book bias is its mean at rest (the middle half of the longest run outside the motion
phase; written likewise).
Every sample is kept: untracked optical samples are written as ``nan`` (the import
drops and counts them), and a start-up transient (samples in the first
:data:`TRANSIENT_WINDOW_S` whose robust z-score against the rest that follows exceeds
:data:`TRANSIENT_Z`) is flagged in the report, never cut. ``span`` keeps only the
samples of a time window (explicit, for a small extract).

**Held repeats and interpolated samples** (``flag`` 2 and 3, :mod:`gcs_core.convert.holds`).
The bus reads every sensor at ``sampling_rate`` (285.7 Hz); the magnetometer measures at
≈ 101 Hz, and in every trial 29 % of the ``imu_mag`` samples repeat the one before exactly
on all three axes (held: a value read once or three times, rarely five) and 35.5 % are
exactly the mean of their two neighbours (interpolated), at rest and in motion alike: with
75-nT steps against ≈ 770 nT of noise, chance gives about one of either per trial. A held
value is the earlier measurement under a later stamp (residual ``(ω × B)·age``, one noise
draw counted twice), an interpolated one no measurement: both are written with their flag,
kept, not used; the report gives their counts, the run lengths and the held values' mean
age. The gyro's exact repeats (0.2–0.6 %, at rest only) are its quantization and stay. The
noise figures are those of the samples used (the white-noise line per sample used of the
irregularly spaced measurements, :func:`gcs_core.noise.measured.allan_deviation`).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gcs_core.convert import ConversionReport, broad_noise
from gcs_core.convert.broad_noise import rest_samples
from gcs_core.convert.broad_text import Site, mission_toml, source_md
from gcs_core.convert.common import check_destination, check_source, staged_directory
from gcs_core.convert.holds import FLAG_NOTE, bus_check, held_repeats, hold_runs
from gcs_core.errors import InputError
from gcs_core.noise import measured as noise_mod

#: the datasets a BROAD trial must hold: name -> (columns, unit)
DATASETS = {
    "imu_gyr": (3, "rad/s"),
    "imu_acc": (3, "m/s²"),
    "imu_mag": (3, "µT"),
    "opt_quat": (4, "1"),
    "opt_pos": (3, "m"),
    "movement": (0, "bool"),
}
UT_TO_NT = 1000.0
#: the start-up window searched for a transient [s], and the robust z-score that flags it
TRANSIENT_WINDOW_S = 2.0
TRANSIENT_Z = 8.0
#: the Earth's centre seen from the laboratory, in its East-North-Up frame [km]: straight
#: down by the Earth's radius at Berlin (52.5° N, 6365 km; the value only labels a place)
LAB_POSITION_KM = (0.0, 0.0, 6365.0)
#: geodetic latitude of the laboratory [deg N]: the paper gives the Control Systems Group of
#: TU Berlin (10623 Berlin) and not the coordinates of the room, so Berlin's, 52.51° N (the
#: TU's Charlottenburg campus); a few km of error in place is < 1e-3° (nothing). Written as
#: ``[ephemeris] latitude_deg``: the gyro then sees the Earth's rate turn with the unit
#: (docs/ground.md), ``ω_E = Ω (0, cos φ, sin φ)`` in ENU.
LAB_LATITUDE_DEG = 52.51
#: the recording date is not published; the epoch only labels the times
EPOCH = "2021-01-01T00:00:00Z"
CITATION = (
    'D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust '
    'Inertial Orientation Estimation", Data 6(7):1-20, 2021, doi:10.3390/data6070072; '
    "github.com/dlaidig/broad, folder data_hdf5. Licence: CC BY 4.0 "
    "(https://creativecommons.org/licenses/by/4.0/)"
)
SENSORS = {"gyro": "GYR", "magnetometer": "MAG", "attitude_reference": "OPT"}
_SITE = Site(CITATION, EPOCH, LAB_POSITION_KM, LAB_LATITUDE_DEG)


#: what h5py raises on a damaged or crafted file (a failed filter, a corrupt header, ...)
_H5_ERRORS = (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError, AttributeError)


def _dataset(f, name: str, cols: int, unit: str, source: Path) -> np.ndarray:
    """Dataset ``name`` as float64 (N,) or (N, cols), every type and shape checked."""
    import h5py

    if name not in f:
        raise InputError(
            f"not a BROAD trial: dataset '{name}' [{unit}] is missing (found: {', '.join(sorted(f.keys())) or 'none'})",
            file=source,
            key=name,
        )
    obj = f.get(name)
    if not isinstance(obj, h5py.Dataset):
        raise InputError(f"'{name}' is not a dataset (a group or a link)", file=source, key=name)
    if obj.dtype.kind not in "fiub":
        raise InputError(f"dataset '{name}' holds {obj.dtype} values, not numbers", file=source, key=name)
    shape = (obj.shape[0],) if cols == 0 and len(obj.shape) == 1 else (obj.shape[0] if obj.shape else 0, cols)
    if len(obj.shape) != len(shape) or tuple(obj.shape) != shape or shape[0] == 0:
        raise InputError(
            f"dataset '{name}' has shape {obj.shape}, expected (N{', ' + str(cols) if cols else ''}) with N > 0",
            file=source,
            key=name,
        )
    return np.asarray(obj[()], dtype=np.float64)


def _read(source: Path) -> tuple[dict[str, np.ndarray], float, str]:
    """The datasets, the sampling rate [Hz] and the info text of a BROAD trial; every
    failure of a damaged or crafted file is one InputError naming the file."""
    import h5py  # foreign HDF5 (GCS's own files go through gcs_core.io.h5store)

    try:
        f = h5py.File(source, "r")
    except FileNotFoundError:
        raise InputError("file not found", file=source) from None
    except _H5_ERRORS as err:
        raise InputError(f"not an HDF5 file ({_first_line(err)})", file=source) from None
    try:
        with f:
            data = {name: _dataset(f, name, cols, unit, source) for name, (cols, unit) in DATASETS.items()}
            if "sampling_rate" not in f.attrs:
                raise InputError(
                    "not a BROAD trial: attribute 'sampling_rate' [Hz] is missing", file=source, key="sampling_rate"
                )
            raw_rate = np.asarray(f.attrs["sampling_rate"])
            if raw_rate.size != 1 or raw_rate.dtype.kind not in "fiu":
                raise InputError("sampling_rate must be one number [Hz]", file=source, key="sampling_rate")
            rate = float(raw_rate.reshape(-1)[0])
            info = f.attrs.get("info", "")
            info = info.decode("utf-8", "replace") if isinstance(info, bytes) else str(info)
    except InputError:
        raise
    except _H5_ERRORS as err:
        raise InputError(f"is damaged or not a BROAD trial ({_first_line(err)})", file=source) from None
    n = {k: v.shape[0] for k, v in data.items()}
    if len(set(n.values())) != 1:
        raise InputError(f"datasets of different lengths: {n}", file=source)
    if not (np.isfinite(rate) and rate > 0):
        raise InputError(f"sampling_rate {rate!r} must be a positive number [Hz]", file=source, key="sampling_rate")
    for name in ("imu_gyr", "imu_mag", "imu_acc"):
        bad = np.flatnonzero(~np.isfinite(data[name]).all(axis=1))
        if bad.size:
            raise InputError(f"dataset '{name}' holds a non-finite value at sample {bad[0]}", file=source, key=name)
    q = data["opt_quat"]
    tracked = np.isfinite(q).all(axis=1)
    norm = np.linalg.norm(q[tracked], axis=1)
    if norm.size and np.max(np.abs(norm - 1.0)) > 1e-3:
        k = int(np.flatnonzero(tracked)[np.argmax(np.abs(norm - 1.0))])
        raise InputError(
            f"dataset 'opt_quat' is not a unit quaternion at sample {k} (norm {np.linalg.norm(q[k]):.6g})",
            file=source,
            key="opt_quat",
        )
    return data, rate, info


def _first_line(err: BaseException) -> str:
    lines = str(err).strip().splitlines()
    return lines[0] if lines else type(err).__name__


def _transients(t: np.ndarray, y: np.ndarray, rest: np.ndarray, what: str) -> list[str]:
    """Start-up samples far from the rest level that follows (module docstring)."""
    first = t <= t[0] + TRANSIENT_WINDOW_S
    ref = rest & ~first
    if ref.sum() < 20:
        return []
    med = np.median(y[ref], axis=0)
    mad = noise_mod.MAD_TO_SIGMA * np.median(np.abs(y[ref] - med), axis=0)
    z = np.abs(y[first] - med) / np.maximum(mad, 1e-12)
    bad = np.flatnonzero((z > TRANSIENT_Z).any(axis=1))
    if not bad.size:
        return []
    # the leading run: samples up to the last flagged one in the window
    last = int(bad[-1])
    return [
        f"{what}: samples 0..{last} (t = {t[0]:.3f} to {t[last]:.3f} s) lie up to "
        f"{z.max():.0f} robust σ from the rest level that follows; kept, flagged"
    ]


def _write_csv(path: Path, header: str, cols: list[np.ndarray], fmt: list[str]) -> int:
    a = np.column_stack(cols)
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(header + "\n")
        np.savetxt(fh, a, fmt=fmt, delimiter=",")
    return int(a.shape[0])


@dataclass(frozen=True)
class Trial:
    """A BROAD trial read (:func:`_read`) and cut to its span, in GCS's units and order.

    t : (n,) [s from the file's first sample]; gyr [rad/s], mag_nT [nT], acc [m/s²] :
    (n, 3); q_gcs : (n, 4) the optical quaternion scalar-last (NaN while untracked), tracked
    : (n,) where it is not; pos : (n, 3) the optical position [m, ENU] as read, lever : (n,
    3) the same from the whole file's mean tracked position; moving : (n,) the motion
    phase; rest : (n,) the samples the noise is measured on
    (:func:`~gcs_core.convert.broad_noise.rest_samples`); info : the file's description;
    rate [Hz]; n_all : samples in the file; keep : (n_all,) those in ``span``.
    """

    t: np.ndarray
    gyr: np.ndarray
    mag_nT: np.ndarray
    acc: np.ndarray
    q_gcs: np.ndarray
    tracked: np.ndarray
    pos: np.ndarray
    lever: np.ndarray
    moving: np.ndarray
    rest: np.ndarray
    info: str
    rate: float
    n_all: int
    keep: np.ndarray
    span: tuple[float, float] | None


@dataclass(frozen=True)
class Flags:
    """Each sample's flag (0, or :data:`~gcs_core.convert.holds.FLAG_HELD` /
    ``FLAG_INTERPOLATED``) of the gyro and the magnetometer."""

    gyro: np.ndarray
    mag: np.ndarray

    @property
    def g_held(self) -> np.ndarray:
        return self.gyro != 0

    @property
    def m_held(self) -> np.ndarray:
        return self.mag != 0


@dataclass
class Notes:
    """What the conversion reports, gathered step by step: start-up transients, the held
    repeats' lines, warnings and notes."""

    transients: list[str] = field(default_factory=list)
    holds: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def _read_span(source: Path, span: tuple[float, float] | None, log: Notes) -> Trial:
    """The trial (:func:`_read`) within ``span`` [s from the first sample], if given."""
    data, rate, info = _read(source)
    n_all = data["imu_gyr"].shape[0]
    t = np.arange(n_all) / rate
    keep = np.ones(n_all, dtype=bool)
    if span is not None:
        lo, hi = float(span[0]), float(span[1])
        if not hi > lo:
            raise InputError(f"span end {hi:g} s must be after its start {lo:g} s", key="span")
        keep = (t >= lo) & (t <= hi)
        if keep.sum() < 100:
            raise InputError(
                f"span [{lo:g}, {hi:g}] s holds {int(keep.sum())} samples of {t[-1]:.1f} s; at least 100 needed",
                key="span",
            )
        log.warnings.append(f"extract: samples of t = {lo:g} to {hi:g} s only ({int(keep.sum())} of {n_all})")
    d = {k: v[keep] for k, v in data.items()}
    moving = d["movement"].astype(bool)
    q = d["opt_quat"]
    q_gcs = np.column_stack([q[:, 1:4], q[:, 0]])  # (w,x,y,z) -> (x,y,z,w), same C_BI
    tracked = np.isfinite(q_gcs).all(axis=1)
    if not tracked.any():
        raise InputError("dataset 'opt_quat' holds no tracked sample (all NaN)", file=source, key="opt_quat")
    lever = d["opt_pos"] - np.nanmean(data["opt_pos"], axis=0)
    return Trial(
        t=t[keep],
        gyr=d["imu_gyr"],
        mag_nT=d["imu_mag"] * UT_TO_NT,
        acc=d["imu_acc"],
        q_gcs=q_gcs,
        tracked=tracked,
        pos=d["opt_pos"],
        lever=lever,
        moving=moving,
        rest=rest_samples(moving),
        info=info,
        rate=rate,
        n_all=n_all,
        keep=keep,
        span=span,
    )


def _flag(trial: Trial, log: Notes) -> Flags:
    """Start-up transients, held repeats and interpolated samples, untracked optical samples
    (module docstring): flagged or reported, every sample kept."""
    t, tracked = trial.t, trial.tracked
    for label, y in (("gyro", trial.gyr), ("magnetometer", trial.mag_nT), ("accelerometer", trial.acc)):
        log.transients += _transients(t, y, trial.rest, label)
    dt = 1.0 / trial.rate
    # held repeats and interpolated samples (module docstring), against each channel's quantization
    g_flag, g_lines = bus_check("gyro", trial.gyr, trial.moving, dt)
    m_flag, m_lines = bus_check("magnetometer", trial.mag_nT, trial.moving, dt)
    log.holds += g_lines + m_lines
    lead = int(np.argmax(tracked))
    if lead:
        log.transients.append(
            f"optical reference: untracked for its first {lead} samples "
            f"(t = {t[0]:.3f} to {t[lead - 1]:.3f} s); written as nan"
        )
    untracked = int((~tracked).sum())
    if untracked:
        log.warnings.append(
            f"optical reference: {untracked} untracked samples written as nan (the import drops and counts them)"
        )
    return Flags(g_flag, m_flag)


def _write_tables(tmp: Path, trial: Trial, flags: Flags) -> dict[str, int]:
    """The telemetry, aux and extra CSV files; file -> rows written."""
    t, g_held, m_held = trial.t, flags.g_held, flags.m_held
    (tmp / "telemetry").mkdir()
    (tmp / "extra").mkdir()
    rows = {}
    rows["telemetry/GYR.csv"] = _write_csv(
        tmp / "telemetry/GYR.csv",
        f"# {FLAG_NOTE}\nt,wx,wy,wz,flag" if g_held.any() else "t,wx,wy,wz",
        [t, *trial.gyr.T] + ([flags.gyro] if g_held.any() else []),
        ["%.6f"] + ["%.9g"] * 3 + (["%d"] if g_held.any() else []),
    )
    rows["telemetry/MAG.csv"] = _write_csv(
        tmp / "telemetry/MAG.csv",
        f"# {FLAG_NOTE}\nt,bx,by,bz,flag" if m_held.any() else "t,bx,by,bz",
        [t, *trial.mag_nT.T] + ([flags.mag] if m_held.any() else []),
        ["%.6f"] + ["%.4f"] * 3 + (["%d"] if m_held.any() else []),
    )
    rows["telemetry/OPT.csv"] = _write_csv(
        tmp / "telemetry/OPT.csv", "t,q1,q2,q3,q4", [t, *trial.q_gcs.T], ["%.6f"] + ["%.10f"] * 4
    )
    rows["extra/acc.csv"] = _write_csv(tmp / "extra/acc.csv", "t,ax,ay,az", [t, *trial.acc.T], ["%.6f"] + ["%.6g"] * 3)
    rows["extra/opt_pos.csv"] = _write_csv(
        tmp / "extra/opt_pos.csv", "t,x,y,z", [t, *trial.pos.T], ["%.6f"] + ["%.6g"] * 3
    )
    placed = np.isfinite(trial.lever).all(axis=1)
    rows["aux.csv"] = _write_csv(
        tmp / "aux.csv", "t,pos_x,pos_y,pos_z", [t[placed], *trial.lever[placed].T], ["%.6f"] + ["%.6f"] * 3
    )
    rows["extra/movement.csv"] = _write_csv(
        tmp / "extra/movement.csv", "t,movement", [t, trial.moving.astype(float)], ["%.6f", "%d"]
    )
    return rows


def _conversion_json(source: Path, rows: dict[str, int], trial: Trial, flags: Flags, log: Notes) -> str:
    """conversion.json: what was written, flagged and estimated."""
    return (
        json.dumps(
            {
                "source": str(source),
                "format": "broad",
                "rows": rows,
                "transients": log.transients,
                "held_repeats": {
                    "flags": FLAG_NOTE,
                    "magnetometer": {str(v): int((flags.mag == v).sum()) for v in (2, 3)},
                    "gyro": {str(v): int((flags.gyro == v).sum()) for v in (2, 3)},
                    "magnetometer_runs": {str(k): v for k, v in hold_runs(held_repeats(trial.mag_nT)).items()},
                    "report": log.holds,
                },
                "warnings": log.warnings,
                "notes": log.notes,
                "citation": CITATION,
            },
            indent=2,
        )
        + "\n"
    )


def _report(source: Path, out: Path, rows: dict[str, int], log: Notes) -> ConversionReport:
    return ConversionReport(
        format="broad",
        source=source,
        out=out,
        rows=int(max(rows.values(), default=0)),
        samples=dict(rows),
        files=tuple(sorted(rows)) + ("mission.toml", "SOURCE.md"),
        notes=tuple(f"transient (kept): {x}" for x in log.transients)
        + tuple(f"repeats: {x}" for x in log.holds)
        + tuple(f"warning: {x}" for x in log.warnings)
        + tuple(log.notes),
    )


def convert(
    source: Path,
    out: Path,
    *,
    span: tuple[float, float] | None = None,
    name: str | None = None,
    overwrite: bool = False,
) -> ConversionReport:
    """Convert one BROAD trial file into the mission directory ``out`` (module docstring).

    Parameters
    ----------
    source : the trial's ``.hdf5`` file.
    out : the mission directory to create (refused when non-empty unless ``overwrite``).
    span : optional ``(start, end)`` [s from the file's first sample]: keep only the
        samples in it (a small extract; the report says so).
    name : mission name (default ``broad-<file stem>``).

    Raises
    ------
    InputError naming the file and dataset that do not match, or the output directory.
    """
    source, out = Path(source), Path(out)
    check_source(source, "broad")
    check_destination(source, out, overwrite=overwrite)  # before the read: fail fast
    log = Notes()
    trial = _read_span(source, span, log)
    flags = _flag(trial, log)
    noise = broad_noise.estimate(trial, flags, source, log.warnings)
    log.notes += noise.notes()
    with staged_directory(out, overwrite=overwrite, source=source) as tmp:
        rows = _write_tables(tmp, trial, flags)
        n_flag = (int((flags.mag == 2).sum()), int((flags.mag == 3).sum()))
        toml = mission_toml(name or f"broad-{source.stem}", source, noise, n_flag, _SITE)
        (tmp / "mission.toml").write_text(toml, encoding="utf-8")
        (tmp / "SOURCE.md").write_text(source_md(source, trial, log, _SITE), encoding="utf-8")
        lic = source.parent / "LICENSE"
        if lic.is_file():
            shutil.copyfile(lic, tmp / "LICENSE")
        else:
            log.warnings.append(f"no LICENSE beside {source.name}: the mission states CC BY 4.0 in SOURCE.md")
        report = _report(source, out, rows, log)
        (tmp / "conversion.json").write_text(_conversion_json(source, rows, trial, flags, log), encoding="utf-8")
    return report
