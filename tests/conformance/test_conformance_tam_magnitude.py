"""Conformance: TAM1 field magnitude of the sunpoint-nominal example against IGRF.

The example (../shared/examples/sunpoint-nominal, made by an independent simulator)
carries a magnetometer with no calibration error and 25 nT of noise per axis. The
magnitude |B| does not depend on attitude or alignment, so |B_measured| − |B_IGRF| at the
interpolated ephemeris position isolates the time, frame (GMST), ephemeris interpolation
and IGRF chain: its RMS must be the noise along the field, 25 nT (the perpendicular noise
adds only ~σ²/|B| ≈ 0.02 nT). A wrong generation (IGRF-13's forecast instead of IGRF-14),
a truncated degree or a wrong Earth rotation shows here as excess RMS or bias.
"""

import numpy as np

from gcs_core.ephem.ephemeris import Ephemeris
from gcs_core.ephem.geomag import GeomagField

EPOCH = "2024-03-20T06:00:00Z"
noise_nT = 25.0


def _read(path):
    return np.genfromtxt(path, delimiter=",", names=True, comments="#")


def test_tam_magnitude_residual_is_the_noise(example_dir):
    e = _read(example_dir / "ephemeris.csv")
    eph = Ephemeris(
        e["t"],
        np.column_stack([e["rx"], e["ry"], e["rz"]]),
        np.column_stack([e["vx"], e["vy"], e["vz"]]),
        np.column_stack([e["sx"], e["sy"], e["sz"]]),
        source=example_dir / "ephemeris.csv",
    )
    m = _read(example_dir / "telemetry" / "TAM1.csv")
    ok = np.isfinite(m["bx"]) & np.isfinite(m["by"]) & np.isfinite(m["bz"])
    t = m["t"][ok]
    B_meas = np.linalg.norm(np.column_stack([m["bx"], m["by"], m["bz"]])[ok], axis=1)
    r = eph.position(t, what="TAM1 telemetry")
    B_ref = GeomagField(EPOCH).field_magnitude(t, r)
    d = B_meas - B_ref
    rms = np.sqrt(np.mean(d**2))
    assert abs(rms - noise_nT) < 0.1 * noise_nT, f"RMS {rms:.2f} nT"
    # no systematic offset: the mean of N samples of 25 nT noise is within 4 sigma/sqrt(N)
    assert abs(np.mean(d)) < 4 * noise_nT / np.sqrt(d.size), f"mean {np.mean(d):.2f} nT"
