"""The Astro Pi magnetometer on the ISS: GCS's discovery against the ellipsoid fit.

Data: Raspberry Pi Foundation, "Astro Pi Flight Data Analysis" (CC BY-SA 4.0), converted
by ``gcs convert astropi`` into ``sample_data/missions/real-astropi-iss``.

Prints, in µT, the residual RMS at every step of ``gcs discover`` (fitted span and held-out
blocks, the same 20-block split as the session) and the same numbers for the alternative a
user tries first: an attitude-independent ellipsoid fit of the field magnitude,

    minimize Σ_k (|A (B_k − b)| − |B_IGRF,k|)²,   A symmetric 3×3 (6), b (3)

(Gauss–Newton from A = I, b = mean; the magnitude alone, so no attitude). Its calibrated
vectors are then rotated onto IGRF in LVLH by the best constant rotation (orthogonal
Procrustes) to give a vector RMS comparable with GCS's.

    python benchmarks/astropi_ellipsoid.py [MISSION_OR_CONFIG [SOURCE_CSV]]

With the published CSV (``../shared/real/astropi-iss/`` by default) it also fits a bias and
a general 3×3 by linear least squares against IGRF in LVLH along the TLE orbit and along
the file's own latitude and longitude, the issue's first look.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np

from gcs_core.config import default_config, load_config
from gcs_core.convert.astropi import procrustes_mounting
from gcs_core.ephem.ephemeris import Ephemeris
from gcs_core.ephem.geomag import GeomagField
from gcs_core.estimators.batch.least_squares import batch_fit
from gcs_core.frames.reference import reference_dcm
from gcs_core.io.importer import load_mission
from gcs_core.session import Analysis

UT = 1000.0  # nT per µT


def _rms(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def gcs_steps(target: Path) -> list[tuple[str, float, float, float, float]]:
    """Per step: label, fitted and held-out RMS [µT], their normalized values, the RMS of the
    magnitude residual [µT] and of the direction error [deg] on the fitted span."""
    cfg = load_config(target) if target.suffix == ".toml" else default_config(target)
    a = Analysis(cfg, mission=load_mission(cfg.mission))
    a.fit()
    a.first_step()
    masks = a.holdout_masks()
    rows = []

    def record(label):
        res = a.result
        r = res.residuals["MAG"]
        fitted = _rms(r.residual[r.used])
        train = batch_fit(a.problem, a.batch_options(), edited=masks, initial=res.state.values())
        rt = train.residuals["MAG"]
        held = _rms(rt.residual[masks["MAG"] & rt.valid])
        y = next(s for s in a.problem.sensors if s.name == "MAG").y
        yhat = y - r.residual
        mag = _rms((np.linalg.norm(y, axis=1) - np.linalg.norm(yhat, axis=1))[r.used])
        # the residual across the predicted field, as an angle (a direction error)
        u = yhat / np.linalg.norm(yhat, axis=1)[:, None]
        perp = r.residual - np.sum(r.residual * u, axis=1)[:, None] * u
        ang = np.degrees(_rms((np.linalg.norm(perp, axis=1) / np.linalg.norm(yhat, axis=1))[r.used]))
        rows.append(
            (label, fitted / UT, held / UT, r.rms_normalized, a.holdout_rms.get("MAG", float("nan")), mag / UT, ang)
        )

    record("fit (bias, attitude)")
    while True:
        n = len(a.steps)
        a.discover(max_steps=1)
        if len(a.steps) == n:
            break
        record(f"+ {a.steps[-1].effect}")
    print(f"stopped: {a.stop_reason}")
    return rows, a


def windowed_rotation(a: Analysis, window_s: float) -> float:
    """RMS per component [µT] left when the final prediction is turned onto the data by a
    separate best rotation in each window (how much a varying attitude could explain)."""
    r = a.result.residuals["MAG"]
    sd = next(s for s in a.problem.sensors if s.name == "MAG")
    y, t = sd.y, sd.t
    yhat = y - r.residual
    out = np.empty_like(y)
    block = (t // window_s).astype(int)
    for b in np.unique(block):
        k = block == b
        U, _, Vt = np.linalg.svd(y[k].T @ yhat[k])
        R = U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt
        out[k] = y[k] - yhat[k] @ R.T
    return _rms(out[r.used]) / UT


def ellipsoid_fit(B, ref_mag, iterations=50):
    """Symmetric A (3, 3) and b (3,) minimizing Σ (|A (B − b)| − |B_ref|)² (Gauss–Newton)."""
    iu = np.triu_indices(3)
    scale = np.mean(ref_mag) / np.mean(np.linalg.norm(B - B.mean(0), axis=1))
    p = np.concatenate([(np.eye(3) * scale)[iu], B.mean(0)])

    def unpack(p):
        A = np.zeros((3, 3))
        A[iu] = p[:6]
        return A + np.triu(A, 1).T, p[6:]

    for _ in range(iterations):
        A, b = unpack(p)
        d = B - b
        u = d @ A.T
        m = np.linalg.norm(u, axis=1)
        r = m - ref_mag
        g = u / m[:, None]  # ∂m/∂u
        J = np.empty((B.shape[0], 9))
        for k, (i, j) in enumerate(zip(*iu)):
            # ∂u/∂A_ij = e_i d_j (+ e_j d_i off the diagonal)
            J[:, k] = g[:, i] * d[:, j] + (g[:, j] * d[:, i] if i != j else 0.0)
        J[:, 6:] = -g @ A
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        p = p + step
        if np.max(np.abs(step[6:])) < 1e-3:
            break
    return unpack(p)


def ellipsoid(target: Path):
    cfg = load_config(target) if target.suffix == ".toml" else default_config(target)
    m = load_mission(cfg.mission)
    tab = m.telemetry["MAG"]
    t, B = tab.t, tab.stack(("bx", "by", "bz"))
    eph = Ephemeris.from_table(m.ephemeris_table)
    r, v = eph.state(t)
    B_I = GeomagField(m.spec.epoch).field_I(t, r)
    B_L = np.einsum("nij,nj->ni", reference_dcm("earth_pointing", r, v), B_I)
    a = Analysis(cfg, mission=m)
    held = a.holdout_masks()["MAG"]
    train = ~held
    A, b = ellipsoid_fit(B[train], np.linalg.norm(B_I[train], axis=1))
    cal = (B - b) @ A.T
    dm = np.linalg.norm(cal, axis=1) - np.linalg.norm(B_I, axis=1)
    # the calibrated vectors against IGRF in LVLH through the best constant rotation
    R, off = procrustes_mounting(B_L[train], cal[train])  # B_L ≈ R cal + off
    resid = B_L - cal @ R.T - off
    vec = lambda k: _rms(resid[k]) / UT
    return (_rms(dm[train]) / UT, _rms(dm[held]) / UT, vec(train), vec(held))


def residual_structure(a: Analysis) -> str:
    """The final residual's correlation over time and its RMS [µT] by latitude band."""
    r = a.result.residuals["MAG"]
    sd = next(s for s in a.problem.sensors if s.name == "MAG")
    eph = Ephemeris.from_table(a.mission.ephemeris_table)
    pos, _ = eph.state(sd.t)
    lat = np.degrees(np.arcsin(pos[:, 2] / np.linalg.norm(pos, axis=1)))
    x = r.residual - r.residual[r.used].mean(axis=0)
    lags = {"1 min": 12, "10 min": 120, "30 min": 360}
    corr = {k: float(np.mean([np.corrcoef(x[:-n, j], x[n:, j])[0, 1] for j in range(3)])) for k, n in lags.items()}
    bands = [(0, 15), (15, 30), (30, 45), (45, 90)]
    rms = [_rms(r.residual[(np.abs(lat) >= lo) & (np.abs(lat) < hi) & r.used]) / UT for lo, hi in bands]
    return (
        "residual correlation after "
        + ", ".join(f"{k}: {v:.2f}" for k, v in corr.items())
        + "; RMS by |latitude| "
        + ", ".join(f"{lo}-{hi}°: {v:.2f} µT" for (lo, hi), v in zip(bands, rms))
    )


def linear_fit_rms(B_S, B_L, train, held):
    """RMS per component [µT] of the linear fit ``B_S ≈ A B_L + b`` (bias and a general
    3×3, least squares on ``train``), on ``train`` and ``held``."""
    X = np.column_stack([B_L, np.ones(len(B_L))])
    coef = np.linalg.lstsq(X[train], B_S[train], rcond=None)[0]
    res = B_S - X @ coef
    return _rms(res[train]) / UT, _rms(res[held]) / UT


def file_positions(target: Path, source_csv: Path):
    """Bias + 3×3 against IGRF in LVLH along the TLE orbit and along the file's own
    latitude/longitude (at the TLE's radius), fitted and held-out RMS [µT] of each."""
    import csv

    from gcs_core.ephem.timescale import gmst_rad

    cfg = load_config(target) if target.suffix == ".toml" else default_config(target)
    m = load_mission(cfg.mission)
    tab = m.telemetry["MAG"]
    t, B = tab.t, tab.stack(("bx", "by", "bz"))
    held = Analysis(cfg, mission=m).holdout_masks()["MAG"]
    eph = Ephemeris.from_table(m.ephemeris_table)
    field = GeomagField(m.spec.epoch)
    r, v = eph.state(t)
    B_L = np.einsum("nij,nj->ni", reference_dcm("earth_pointing", r, v), field.field_I(t, r))
    with open(source_csv, newline="") as fh:
        rows = list(csv.DictReader(fh))
    lat = np.radians([float(x["Latitude"]) for x in rows])
    lon = np.radians([float(x["Longitude"]) for x in rows])
    keep = np.asarray(tab.lines) - 2 - 2  # file line of each kept row -> source row
    lat, lon = lat[keep], lon[keep]
    rad = np.linalg.norm(r, axis=1)
    r_E = rad[:, None] * np.column_stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    g = gmst_rad(m.spec.epoch, t)
    c, s_ = np.cos(g), np.sin(g)
    r_f = np.column_stack([c * r_E[:, 0] - s_ * r_E[:, 1], s_ * r_E[:, 0] + c * r_E[:, 1], r_E[:, 2]])
    v_f = np.gradient(r_f, t, axis=0)
    B_Lf = np.einsum("nij,nj->ni", reference_dcm("earth_pointing", r_f, v_f), field.field_I(t, r_f))
    return linear_fit_rms(B, B_L, ~held, held), linear_fit_rms(B, B_Lf, ~held, held)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    target = Path(argv[0]) if argv else ROOT / "sample_data" / "configs" / "real-astropi-iss.toml"
    print(f"Astro Pi magnetometer on the ISS ({target})")
    print(
        f"{'step':40s} {'fitted µT':>10s} {'held-out µT':>12s} {'norm.':>7s} {'held norm.':>10s}"
        f" {'|B| µT':>7s} {'angle °':>8s}"
    )
    rows, a = gcs_steps(target)
    for label, fit, held, nrm, hnrm, mag, ang in rows:
        print(f"{label:40s} {fit:10.3f} {held:12.3f} {nrm:7.2f} {hnrm:10.2f} {mag:7.3f} {ang:8.2f}")
    print(
        "(µT: RMS per component; |B|: RMS of the magnitude residual; angle: RMS of the residual "
        "across the predicted field, as a direction error)"
    )
    print(
        "after the last step, a separate best rotation per window leaves "
        + ", ".join(f"{windowed_rotation(a, w):.3f} µT ({w / 60:.0f} min)" for w in (5400.0, 600.0))
    )
    print(residual_structure(a))
    mag_fit, mag_held, vec_fit, vec_held = ellipsoid(target)
    print()
    source = Path("/work/shared/real/astropi-iss/astro-pi-mk2-commissioning-ir.csv")
    if len(argv) > 1:
        source = Path(argv[1])
    if source.is_file():
        (tf, th), (ff, fh) = file_positions(target, source)
        print(
            f"bias + general 3x3 against IGRF in LVLH (linear least squares): along the TLE orbit "
            f"{tf:.3f} µT (held-out {th:.3f}); along the file's own latitude/longitude "
            f"{ff:.3f} µT ({fh:.3f})"
        )
    print("ellipsoid fit of |B| (bias + symmetric 3x3, attitude-independent):")
    print(f"  magnitude residual RMS   fitted {mag_fit:.3f} µT, held-out {mag_held:.3f} µT")
    print(
        f"  vector RMS per component after the best constant rotation onto LVLH: "
        f"fitted {vec_fit:.3f} µT, held-out {vec_held:.3f} µT"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
