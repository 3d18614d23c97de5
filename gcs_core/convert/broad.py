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
from pathlib import Path

import numpy as np

from gcs_core.convert import ConversionReport
from gcs_core.convert.broad_text import mission_toml, source_md
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
_SITE = (CITATION, EPOCH, LAB_POSITION_KM, LAB_LATITUDE_DEG)


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


def _rest(moving: np.ndarray) -> np.ndarray:
    """(N,) the samples the noise and the gyro's rest bias are measured on: the middle
    half of the longest run outside the motion phase (the unit is often picked up, or
    still swinging, a few seconds on either side of the phase flagged as motion)."""
    still = ~np.asarray(moving, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
    runs = edges.reshape(-1, 2)
    out = np.zeros(still.size, dtype=bool)
    if runs.size:
        lo, hi = runs[int(np.argmax(runs[:, 1] - runs[:, 0]))]
        q = (hi - lo) // 4
        out[lo + q : hi - q] = True
    return out


def _floor(line: np.ndarray, spread: np.ndarray, tiny: float, what: str, unit: str, warnings: list[str]) -> np.ndarray:
    """``line`` where it is a positive number; elsewhere the per-sample spread, else ``tiny``."""
    bad = ~(np.isfinite(line) & (line > 0))
    if not bad.any():
        return line
    out = np.where(bad, np.where(np.isfinite(spread) & (spread > 0), spread, tiny), line)
    warnings.append(
        f"{what}: no noise measurable at rest on {int(bad.sum())} axis(es); "
        f"written {np.array2string(out, precision=4)} {unit} from the per-sample "
        "spread (or a floor): check it"
    )
    return out


def _write_csv(path: Path, header: str, cols: list[np.ndarray], fmt: list[str]) -> int:
    a = np.column_stack(cols)
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(header + "\n")
        np.savetxt(fh, a, fmt=fmt, delimiter=",")
    return int(a.shape[0])


def _rms(v) -> float:
    v = np.asarray(v, dtype=float)
    return float(np.sqrt(np.mean(v * v)))


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
    data, rate, info = _read(source)
    n_all = data["imu_gyr"].shape[0]
    t = np.arange(n_all) / rate
    keep = np.ones(n_all, dtype=bool)
    warnings, notes, transients = [], [], []
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
        warnings.append(f"extract: samples of t = {lo:g} to {hi:g} s only ({int(keep.sum())} of {n_all})")
    d = {k: v[keep] for k, v in data.items()}
    t = t[keep]
    moving = d["movement"].astype(bool)
    rest0 = _rest(moving)
    gyr, mag_nT, acc = d["imu_gyr"], d["imu_mag"] * UT_TO_NT, d["imu_acc"]
    q = d["opt_quat"]
    q_gcs = np.column_stack([q[:, 1:4], q[:, 0]])  # (w,x,y,z) -> (x,y,z,w), same C_BI
    tracked = np.isfinite(q_gcs).all(axis=1)
    if not tracked.any():
        raise InputError("dataset 'opt_quat' holds no tracked sample (all NaN)", file=source, key="opt_quat")
    for label, y in (("gyro", gyr), ("magnetometer", mag_nT), ("accelerometer", acc)):
        transients += _transients(t, y, rest0, label)
    dt = 1.0 / rate
    # held repeats and interpolated samples (module docstring), against each channel's quantization
    g_flag, g_lines = bus_check("gyro", gyr, moving, dt)
    m_flag, m_lines = bus_check("magnetometer", mag_nT, moving, dt)
    holds = g_lines + m_lines
    g_held, m_held = g_flag != 0, m_flag != 0
    s_gyr = noise_mod.white_noise(t[~g_held], gyr[~g_held])
    s_mag = noise_mod.white_noise(t[~m_held], mag_nT[~m_held])  # the samples used
    lead = int(np.argmax(tracked))
    if lead:
        transients.append(
            f"optical reference: untracked for its first {lead} samples "
            f"(t = {t[0]:.3f} to {t[lead - 1]:.3f} s); written as nan"
        )
    untracked = int((~tracked).sum())
    if untracked:
        warnings.append(
            f"optical reference: {untracked} untracked samples written as nan (the import drops and counts them)"
        )

    # noise from the data (gcs_core.noise.measured), of the samples the fit uses
    s_opt = noise_mod.white_noise(t[tracked], q_gcs[tracked], quaternion=True)
    if rest0.sum() < 64:
        raise InputError(
            f"only {int(rest0.sum())} samples at rest: too few to measure the noise", file=source, key="movement"
        )
    # the white-noise lines of the rest (consecutive samples of the unit are correlated:
    # the per-sample spread s_* understates the noise slow parameters see)
    g_curves = noise_mod.allan_deviation(t[rest0], gyr[rest0])
    g_terms = [noise_mod.gyro_terms(c) for c in g_curves]
    arw = _rms([g.arw for g in g_terms])
    rrw = _rms([g.rrw for g in g_terms])
    m_use = rest0 & ~m_held  # irregularly spaced where held repeats are left out: per sample used
    m_dt = noise_mod.mean_interval(t[m_use])
    m_line = np.array([noise_mod.white_level(c, m_dt)[0] for c in noise_mod.allan_deviation(t[m_use], mag_nT[m_use])])
    opt_rest = rest0 & tracked
    if opt_rest.sum() < 64:
        raise InputError(
            f"only {int(opt_rest.sum())} tracked optical samples at rest: too few to measure the noise",
            file=source,
            key="opt_quat",
        )
    o_line = np.array(
        [
            noise_mod.white_level(c, dt)[0]
            for c in noise_mod.allan_deviation(t[opt_rest], q_gcs[opt_rest], quaternion=True)
        ]
    )
    # a channel constant at rest (or quantized coarser than its noise) shows no noise there:
    # its per-sample spread over the whole span, else a floor, stands in (and is reported)
    m_line = _floor(m_line, s_mag, 1e-3, "magnetometer", "nT", warnings)
    o_line = _floor(o_line, s_opt, 1e-9, "optical reference", "rad", warnings)
    if not arw > 0:
        arw = float(_floor(np.array([0.0]), np.array([_rms(s_gyr)]), 1e-9, "gyro", "rad/s", warnings)[0]) * np.sqrt(dt)
    bias0 = gyr[rest0].mean(axis=0)
    notes.append(
        f"noise estimated from the telemetry: per-sample spread (second differences) "
        f"gyro {np.array2string(s_gyr, precision=4)} rad/s, magnetometer "
        f"{np.array2string(s_mag, precision=1)} nT, optical "
        f"{np.array2string(s_opt, precision=7)} rad; white-noise lines at rest "
        f"(Allan deviation): gyro ARW {arw:.4g} rad/s^0.5, magnetometer "
        f"{np.array2string(m_line, precision=1)} nT per sample used "
        f"(every {1e3 * m_dt:.3f} ms on average), optical "
        f"{np.array2string(o_line, precision=7)} rad per sample"
    )
    notes.append(f"gyro data-book bias = mean over the rest ({int(rest0.sum())} samples)")

    with staged_directory(out, overwrite=overwrite, source=source) as tmp:
        (tmp / "telemetry").mkdir()
        (tmp / "extra").mkdir()
        rows = {}
        rows["telemetry/GYR.csv"] = _write_csv(
            tmp / "telemetry/GYR.csv",
            f"# {FLAG_NOTE}\nt,wx,wy,wz,flag" if g_held.any() else "t,wx,wy,wz",
            [t, *gyr.T] + ([g_flag] if g_held.any() else []),
            ["%.6f"] + ["%.9g"] * 3 + (["%d"] if g_held.any() else []),
        )
        rows["telemetry/MAG.csv"] = _write_csv(
            tmp / "telemetry/MAG.csv",
            f"# {FLAG_NOTE}\nt,bx,by,bz,flag" if m_held.any() else "t,bx,by,bz",
            [t, *mag_nT.T] + ([m_flag] if m_held.any() else []),
            ["%.6f"] + ["%.4f"] * 3 + (["%d"] if m_held.any() else []),
        )
        rows["telemetry/OPT.csv"] = _write_csv(
            tmp / "telemetry/OPT.csv", "t,q1,q2,q3,q4", [t, *q_gcs.T], ["%.6f"] + ["%.10f"] * 4
        )
        rows["extra/acc.csv"] = _write_csv(tmp / "extra/acc.csv", "t,ax,ay,az", [t, *acc.T], ["%.6f"] + ["%.6g"] * 3)
        rows["extra/opt_pos.csv"] = _write_csv(
            tmp / "extra/opt_pos.csv", "t,x,y,z", [t, *d["opt_pos"].T], ["%.6f"] + ["%.6g"] * 3
        )
        pos = d["opt_pos"] - np.nanmean(data["opt_pos"], axis=0)
        placed = np.isfinite(pos).all(axis=1)
        rows["aux.csv"] = _write_csv(
            tmp / "aux.csv", "t,pos_x,pos_y,pos_z", [t[placed], *pos[placed].T], ["%.6f"] + ["%.6f"] * 3
        )
        rows["extra/movement.csv"] = _write_csv(
            tmp / "extra/movement.csv", "t,movement", [t, moving.astype(float)], ["%.6f", "%d"]
        )
        mname = name or f"broad-{source.stem}"
        n_flag = (int((m_flag == 2).sum()), int((m_flag == 3).sum()))
        args = (bias0, arw, rrw, m_line, o_line, s_mag, s_opt, s_gyr, rest0.sum(), n_flag, _SITE)
        toml = mission_toml(mname, source, *args)
        (tmp / "mission.toml").write_text(toml, encoding="utf-8")
        (tmp / "SOURCE.md").write_text(
            source_md(source, info, rate, n_all, span, keep, transients, warnings, holds, _SITE), encoding="utf-8"
        )
        lic = source.parent / "LICENSE"
        if lic.is_file():
            shutil.copyfile(lic, tmp / "LICENSE")
        else:
            warnings.append(f"no LICENSE beside {source.name}: the mission states CC BY 4.0 in SOURCE.md")
        report = ConversionReport(
            format="broad",
            source=source,
            out=out,
            rows=int(max(rows.values(), default=0)),
            samples=dict(rows),
            files=tuple(sorted(rows)) + ("mission.toml", "SOURCE.md"),
            notes=tuple(f"transient (kept): {x}" for x in transients)
            + tuple(f"repeats: {x}" for x in holds)
            + tuple(f"warning: {x}" for x in warnings)
            + tuple(notes),
        )
        (tmp / "conversion.json").write_text(
            json.dumps(
                {
                    "source": str(source),
                    "format": "broad",
                    "rows": rows,
                    "transients": transients,
                    "held_repeats": {
                        "flags": FLAG_NOTE,
                        "magnetometer": {str(v): int((m_flag == v).sum()) for v in (2, 3)},
                        "gyro": {str(v): int((g_flag == v).sum()) for v in (2, 3)},
                        "magnetometer_runs": {str(k): v for k, v in hold_runs(held_repeats(mag_nT)).items()},
                        "report": holds,
                    },
                    "warnings": warnings,
                    "notes": notes,
                    "citation": CITATION,
                },
                indent=2,
            )
            + "\n",
            encoding="utf-8",
        )
    return report
