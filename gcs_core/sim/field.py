"""Geomagnetic truth field: IGRF at the spacecraft's geocentric position (ICD §4).

The field is evaluated with ``ppigrf.igrf_gc`` (IGRF-14, all degrees to 13) in
geocentric spherical coordinates of the Earth-fixed frame and rotated back to GCI::

    r_E = T3(GMST) r_I,   θ = acos(z_E/|r|) (colatitude),   φ = atan2(y_E, x_E)
    B_E = B_r r̂ + B_θ θ̂ + B_φ φ̂
    r̂ = (sθ cφ, sθ sφ, cθ),  θ̂ = (cθ cφ, cθ sφ, −sθ),  φ̂ = (−sφ, cφ, 0)
    B_I = T3(GMST)ᵀ B_E

GMST is the simulator's own (:func:`gcs_core.sim.astro.gmst_rad`). The IGRF
coefficients (linear in time between their 5-year epochs) are evaluated at the two
mission-day boundaries around each sample and interpolated linearly, which is exact.

References
----------
Alken, P. et al., "International Geomagnetic Reference Field: the thirteenth generation",
Earth Planets Space 73, 49 (2021). ppigrf: https://github.com/IAGA-VMOD/ppigrf
"""

from __future__ import annotations

from datetime import timedelta

import numpy as np

from gcs_core.sim.astro import gmst_rad

__all__ = ["igrf_gci"]

_BATCH = 4096


def igrf_gci(epoch, jd0: float, t, r_I_km, *, max_degree: int = 13) -> np.ndarray:
    """IGRF field [nT] in GCI at mission times ``t`` (N,) and positions ``r_I_km`` (N, 3)."""
    import ppigrf  # local import: ppigrf pulls in pandas, slow to import

    t = np.asarray(t, dtype=float)
    r_I = np.asarray(r_I_km, dtype=float)
    if t.size == 0:
        return np.zeros((0, 3))
    g = gmst_rad(jd0, t)
    cg, sg = np.cos(g), np.sin(g)
    # T3(g) r: x_E = c x + s y, y_E = -s x + c y
    xE = cg * r_I[:, 0] + sg * r_I[:, 1]
    yE = -sg * r_I[:, 0] + cg * r_I[:, 1]
    zE = r_I[:, 2]
    rn = np.sqrt(xE**2 + yE**2 + zE**2)
    th = np.arccos(np.clip(zE / rn, -1.0, 1.0))
    ph = np.arctan2(yE, xE)
    # IGRF coefficients are linear in time between their 5-year epochs, so the field at a
    # fixed place is linear in time within a day: evaluate it at the two midnights (mission
    # days) around each sample and interpolate. Exact, and independent of the chunking.
    day = np.floor(t / 86400.0)
    frac = (t / 86400.0 - day)[:, None]
    B_sph = np.empty((rn.size, 3))
    for d in np.unique(day):
        idx = np.flatnonzero(day == d)
        dates = [(epoch + timedelta(days=float(d + k))).replace(tzinfo=None) for k in (0, 1)]
        for lo in range(0, idx.size, _BATCH):  # ppigrf holds (N, 195) arrays: keep N small
            sl = idx[lo : lo + _BATCH]
            out = ppigrf.igrf_gc(rn[sl], np.degrees(th[sl]), np.degrees(ph[sl]), dates, max_degree=max_degree)
            both = np.stack(out, -1)  # (2 dates, n, 3 components)
            B_sph[sl] = (1.0 - frac[sl]) * both[0] + frac[sl] * both[1]
    Br, Bt, Bp = B_sph[:, 0], B_sph[:, 1], B_sph[:, 2]
    st, ct, sp, cp = np.sin(th), np.cos(th), np.sin(ph), np.cos(ph)
    bx = Br * st * cp + Bt * ct * cp - Bp * sp
    by = Br * st * sp + Bt * ct * sp + Bp * cp
    bz = Br * ct - Bt * st
    # T3(g)^T B_E
    return np.stack([cg * bx - sg * by, sg * bx + cg * by, bz], axis=-1)
