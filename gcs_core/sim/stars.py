"""Synthetic star catalog and the fixed-head star tracker (FHST) truth model (Eq 4-29, 4-30).

Catalog: ``n`` stars uniform on the sphere (``z`` uniform in [−1, 1], RA uniform),
magnitudes in [2, 6] with the cumulative count growing as ``10^(0.45 m)`` (faint stars
dominate, as in the sky). Seeded, so every mission sees the same sky.

Tracker, per frame at ``t`` (``t' = t + time_offset``)::

    F_I' = unit(F_I + β − (F_I·β) F_I),  β = (v_earth + v_sc)/c   (stellar aberration, if on)
    F_S  = M C_BI(t') F_I'                                           (Eq 4-30)
    h = asin(F_Sz) / S_H + n_h,   v = atan2(F_Sy, F_Sx) / S_V + n_v  (Eq 4-29)

with the true ``M`` and ``S_H, S_V``; ``n_h, n_v`` white, or first-order Gauss–Markov
with ``noise_correlation_s`` (:mod:`gcs_core.sim.gauss_markov`). A star is trackable when ``|asin F_Sz|`` and
``|atan2(F_Sy, F_Sx)|`` are within ``fov_deg`` (half width). One star is reported per frame,
drawn among the trackable ones with probability ∝ brightness ``10^(−0.4 m)``; the row gives
its catalog (J2000) ``ra, dec`` and ``mag``. With a misidentification fraction ``f``, that
fraction of rows reports another trackable star's catalog entry (the measured ``h, v``
stay those of the observed star).

No data while the boresight (sensor ``+x``) is within ``earth_exclusion_deg`` of the Earth
limb (angle to the Earth centre below ``asin(R_E/|r|) + exclusion``) or within
``sun_exclusion_deg`` of the Sun.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from gcs_core.sim import astro, drifts
from gcs_core.sim._rot import rpy_to_dcm, unit
from gcs_core.sim.config import SensorConfig
from gcs_core.sim.gauss_markov import correlated_noise

__all__ = ["StarCatalog", "StarTrackerSim", "aberrate"]


class StarCatalog:
    """Seeded synthetic catalog. Attributes: ``u_I`` (n, 3), ``ra_deg``, ``dec_deg``, ``mag`` (n,)."""

    def __init__(self, seed: int, n: int = 8000, mag_range=(2.0, 6.0)):
        rng = np.random.default_rng(seed)
        z = rng.uniform(-1.0, 1.0, n)
        ra = rng.uniform(0.0, 2 * np.pi, n)
        c = np.sqrt(1.0 - z * z)
        self.u_I = np.stack([c * np.cos(ra), c * np.sin(ra), z], axis=-1)
        self.ra_deg = np.degrees(ra)
        self.dec_deg = np.degrees(np.arcsin(z))
        lo, hi = mag_range
        # Inverse CDF of N(<m) ∝ 10^(0.45 m) on [lo, hi].
        k = 0.45 * np.log(10.0)
        x = rng.uniform(0.0, 1.0, n)
        self.mag = np.log(np.exp(k * lo) + x * (np.exp(k * hi) - np.exp(k * lo))) / k
        self.tree = cKDTree(self.u_I)


def aberrate(u_I, beta) -> np.ndarray:
    """First-order aberration: apparent direction ``unit(u + β − (u·β) u)``, β = v/c. (N, 3)."""
    u_I = np.asarray(u_I, dtype=float)
    beta = np.asarray(beta, dtype=float)
    d = np.einsum("...i,...i->...", u_I, beta)[..., None]
    return unit(u_I + beta - d * u_I)


class StarTrackerSim:
    """FHST rows ``t, h, v, ra, dec, mag`` (ICD §5 ``star_tracker``)."""

    columns = ("t", "h", "v", "ra", "dec", "mag")
    formats = ("%.12g",) * 6

    def __init__(
        self,
        sensor: SensorConfig,
        world,
        catalog: StarCatalog,
        rng: np.random.Generator,
        *,
        stellar_aberration: bool = False,
    ):
        self.s, self.world, self.cat = sensor, world, catalog
        # Star choice and noise use separate streams: the files do not depend on the chunking.
        self.rng, self.rng_pick = (np.random.default_rng(x) for x in rng.integers(2**62, size=2))
        a = np.radians(np.asarray(sensor.value("alignment_deg"), dtype=float))
        self.M = rpy_to_dcm(a[0], a[1], a[2])
        self.scale = np.asarray(sensor.value("scale", (1.0, 1.0)), dtype=float)
        self.fov = np.radians(float(sensor.value("fov_deg")))
        self.noise = float(sensor.value("noise"))
        self.white, self.gm = correlated_noise(sensor, self.noise, 2, self.rng)
        self.tau = float(sensor.value("time_offset_s", 0.0))
        self.sun_excl = np.radians(float(sensor.value("sun_exclusion_deg", 30.0)))
        self.earth_excl = np.radians(float(sensor.value("earth_exclusion_deg", 10.0)))
        self.misid = float(sensor.value("misid_fraction", 0.0))
        self.aberration = stellar_aberration
        self.aux = None  # the mission's aux channels (a bending tracker follows one; drifts.py)
        self.n_occulted = 0
        self.n_misidentified = 0

    def run(self, t_rows: np.ndarray) -> dict[str, np.ndarray]:
        w = self.world
        tt = t_rows + self.tau
        r, v = w.orbit(tt)
        s = w.sun(tt)
        C_SI = drifts.bent_alignment(self.s, self.M, w, self.aux, tt, r, v) @ w.attitude(tt, r, v, s)
        bore_I = C_SI[:, 0, :]
        rn = np.linalg.norm(r, axis=-1)
        ang_earth = np.arccos(np.clip(np.einsum("ij,ij->i", bore_I, -r) / rn, -1, 1))
        ang_sun = np.arccos(np.clip(np.einsum("ij,ij->i", bore_I, unit(s - r)), -1, 1))
        ok = (ang_earth > np.arcsin(astro.R_EARTH_KM / rn) + self.earth_excl) & (ang_sun > self.sun_excl)
        self.n_occulted += int(np.sum(~ok))
        if self.aberration:
            beta = (astro.earth_velocity_km_s(w.jd0, tt) + v) / astro.C_KM_S
        radius = 2.0 * np.sin(0.5 * self.fov * np.sqrt(2.0) * 1.01)  # chord of the FOV corner
        cand = self.cat.tree.query_ball_point(bore_I, radius)
        rows = []
        for k in np.flatnonzero(ok):
            idx = np.asarray(cand[k], dtype=int)
            if idx.size == 0:
                continue
            F_I = self.cat.u_I[idx]
            if self.aberration:
                F_I = aberrate(F_I, beta[k][None, :])
            F_S = F_I @ C_SI[k].T
            h_true = np.arcsin(np.clip(F_S[:, 2], -1, 1))
            v_true = np.arctan2(F_S[:, 1], F_S[:, 0])
            inside = (np.abs(h_true) <= self.fov) & (np.abs(v_true) <= self.fov) & (F_S[:, 0] > 0)
            if not np.any(inside):
                continue
            sel = np.flatnonzero(inside)
            wgt = 10.0 ** (-0.4 * self.cat.mag[idx[sel]])
            j = sel[self.rng_pick.choice(sel.size, p=wgt / wgt.sum())]
            star = idx[j]
            if self.misid > 0 and self.rng_pick.uniform() < self.misid:
                others = idx[idx != star]
                if others.size:
                    star = others[self.rng_pick.integers(others.size)]
                    self.n_misidentified += 1
            rows.append((t_rows[k], h_true[j], v_true[j], star))
        if not rows:
            return {c: np.zeros(0) for c in self.columns}
        t_out = np.array([x[0] for x in rows])
        star = np.array([x[3] for x in rows], dtype=int)
        h_err = drifts.magnitude_error(self.s, self.cat.mag[star])
        h = (np.array([x[1] for x in rows]) + h_err) / self.scale[0]
        vv = np.array([x[2] for x in rows]) / self.scale[1]
        if self.gm is None:
            e = self.rng.standard_normal((h.size, 2)) * self.noise
        else:  # Gauss–Markov noise at the frame times (gauss_markov.py)
            e = self.gm.draw(t_out) + self.rng.standard_normal((h.size, 2)) * self.white
        h, vv = h + e[:, 0], vv + e[:, 1]
        return {
            "t": t_out,
            "h": h,
            "v": vv,
            "ra": self.cat.ra_deg[star],
            "dec": self.cat.dec_deg[star],
            "mag": self.cat.mag[star],
        }
