"""Geomagnetic reference field in GCI: IGRF (or its dipole) at the spacecraft (ICD §4).

The field comes from the internal scalar potential of the International Geomagnetic
Reference Field, with Schmidt semi-normalized associated Legendre functions ``P_n^m``,
reference radius ``a = 6371.2 km``, geocentric radius ``r``, colatitude ``θ``, east
longitude ``φ``:

    V   = a Σ_n (a/r)^(n+1) Σ_m (g_n^m cos mφ + h_n^m sin mφ) P_n^m(cos θ)
    B_r = −∂V/∂r       = Σ_n (n+1)(a/r)^(n+2) Σ_m (g cos mφ + h sin mφ) P_n^m
    B_θ = −∂V/(r ∂θ)   = −Σ_n (a/r)^(n+2) Σ_m (g cos mφ + h sin mφ) dP_n^m/dθ
    B_φ = −∂V/(r sinθ ∂φ) = −(1/sin θ) Σ_n (a/r)^(n+2) Σ_m m (−g sin mφ + h cos mφ) P_n^m

(``B_θ`` points south, ``B_φ`` east.) The Legendre functions come from the recursions

    P_0^0 = 1,  P_1^1 = sin θ,  P_n^n = √((2n−1)/(2n)) sin θ P_{n−1}^{n−1}   (n ≥ 2)
    P_n^m = [(2n−1) cos θ P_{n−1}^m − √((n−1)² − m²) P_{n−2}^m] / √(n² − m²)   (n > m)

differentiated term by term for ``dP/dθ``.

Frames (ICD §2): ``r_E = R3(GMST) r_I`` with GMST by IAU 1982 (UT1 = UTC) and no
precession or nutation; the field found in Earth-fixed axes is rotated back with
``R3(GMST)ᵀ``. Secular variation: the Gauss coefficients are linear in decimal year
between the model epochs of the table (the last interval carries the predictive secular
variation), and GCS evaluates them at each sample's own time, which is exact for that
piecewise-linear model.

The coefficient tables are the IGRF-13 and IGRF-14 ``.shc`` files that the ``ppigrf``
package ships; they are read once per process. The spherical-harmonic sum is evaluated
here, vectorized over points and processed in chunks so that memory stays bounded for
hundreds of thousands of samples. ``tests/reference/test_ref_igrf.py`` checks it against
``ppigrf.igrf_gc`` and published values.

References
----------
Alken, P. et al., "International Geomagnetic Reference Field: the thirteenth
generation", Earth Planets Space 73:49 (2021).
IAGA Working Group V-MOD, IGRF-14 (2024), https://doi.org/10.5281/zenodo.14012302.
Wertz, J. R. (ed.), *Spacecraft Attitude Determination and Control*, Reidel 1978,
§5.2 and Appendix H (Schmidt normalization, recursions).
Langel, R. A., "The main field", in *Geomagnetism* vol. 1, Academic Press 1987.
"""

from __future__ import annotations

import functools
import logging
from datetime import datetime
from importlib import resources

import numpy as np

from gcs_core.ephem import timescale
from gcs_core.errors import InputError

__all__ = ["GeomagField", "IGRF_REFERENCE_RADIUS_KM", "load_igrf_coefficients", "spherical_harmonic_field"]

log = logging.getLogger(__name__)

#: IGRF magnetic reference radius [km].
IGRF_REFERENCE_RADIUS_KM = 6371.2
_CHUNK = 20000  # points per evaluation chunk (bounded memory)
_POLE_SIN = 1e-10  # |sin θ| floor: moves a point ≤ 1 mm off a pole


@functools.lru_cache(maxsize=4)
def load_igrf_coefficients(generation: int = 14):
    """Gauss coefficients of IGRF-``generation`` from the table shipped with ``ppigrf``.

    Returns
    -------
    years : (K,) model epochs in decimal years (the last is the end of the predictive
        secular variation, e.g. 2030.0 for IGRF-14).
    g, h : (K, 14, 14) coefficients [nT] indexed ``[k, n, m]`` (zero where undefined).
    """
    name = {13: "IGRF13.shc", 14: "IGRF14.shc"}.get(int(generation))
    if name is None:
        raise InputError(f"IGRF generation {generation} is not available (use 13 or 14)", key="igrf_generation")
    text = resources.files("ppigrf").joinpath(name).read_text()
    rows = [ln.split() for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    n_max = int(rows[0][1])
    years = np.array([float(x) for x in rows[1]])
    g = np.zeros((years.size, n_max + 1, n_max + 1))
    h = np.zeros_like(g)
    for row in rows[2:]:
        n, m = int(row[0]), int(row[1])
        vals = np.array([float(x) for x in row[2:]])
        if m >= 0:
            g[:, n, m] = vals
        else:
            h[:, n, -m] = vals
    for a in (years, g, h):
        a.setflags(write=False)
    return years, g, h


def spherical_harmonic_field(
    r_km,
    theta,
    phi,
    g,
    h,
    *,
    max_degree: int,
    min_degree: int = 1,
    gdot=None,
    hdot=None,
    dt_yr=None,
    a_km: float = IGRF_REFERENCE_RADIUS_KM,
):
    """Internal-source field ``(B_r, B_θ, B_φ)`` [nT] at geocentric points (module docstring).

    Parameters
    ----------
    r_km, theta, phi : (P,) radius [km], colatitude [rad], east longitude [rad].
    g, h : (≥n+1, ≥n+1) Gauss coefficients [nT], indexed ``[n, m]``.
    max_degree, min_degree : degrees summed.
    gdot, hdot, dt_yr : optional secular variation [nT/yr] and (P,) years elapsed since
        the epoch of ``g, h``; each point then uses ``g + gdot dt_yr`` (exact for IGRF's
        piecewise-linear coefficients).

    Returns
    -------
    three (P,) arrays: radial (up), θ (south), φ (east).
    """
    r = np.asarray(r_km, dtype=float)
    ct, st = np.cos(theta), np.sin(theta)
    st = np.where(np.abs(st) < _POLE_SIN, _POLE_SIN, st)
    sv = dt_yr is not None
    N = int(max_degree)
    # cos(mφ), sin(mφ) for m = 0..N, one contiguous row per order
    m_idx = np.arange(N + 1)
    cm = np.cos(np.outer(m_idx, phi))
    sm = np.sin(np.outer(m_idx, phi))
    ratio = a_km / r
    Br = np.zeros_like(r)
    Bt = np.zeros_like(r)
    Bp = np.zeros_like(r)
    # Legendre P[n][m] and dP[n][m] kept for the two previous degrees only.
    P_prev2: list[np.ndarray] = []
    P_prev: list[np.ndarray] = []
    dP_prev2: list[np.ndarray] = []
    dP_prev: list[np.ndarray] = []
    Pnn, dPnn = np.ones_like(r), np.zeros_like(r)  # P_0^0 and its derivative
    rn = ratio**2  # (a/r)^(n+2) at n = 0
    for n in range(0, N + 1):
        P: list[np.ndarray] = [Pnn] * (n + 1)  # every entry is set below
        dP: list[np.ndarray] = [dPnn] * (n + 1)
        if n == 0:
            P[0], dP[0] = Pnn, dPnn
        else:
            # sectoral term from the previous sectoral one
            f = 1.0 if n == 1 else np.sqrt((2.0 * n - 1.0) / (2.0 * n))
            P[n] = f * st * P_prev[n - 1]
            dP[n] = f * (ct * P_prev[n - 1] + st * dP_prev[n - 1])
            for m in range(n):
                k1 = (2.0 * n - 1.0) / np.sqrt(n * n - m * m)
                k2 = np.sqrt(((n - 1.0) ** 2 - m * m) / (n * n - m * m)) if n > 1 else 0.0
                P[m] = k1 * ct * P_prev[m]
                dP[m] = k1 * (ct * dP_prev[m] - st * P_prev[m])
                if k2 != 0.0:
                    P[m] = P[m] - k2 * P_prev2[m]
                    dP[m] = dP[m] - k2 * dP_prev2[m]
        rn = rn * ratio if n > 0 else rn
        if min_degree <= n <= N and n >= 1:
            sr = np.zeros_like(r)
            stt = np.zeros_like(r)
            sp = np.zeros_like(r)
            for m in range(n + 1):
                gnm, hnm = g[n, m], h[n, m]
                if sv:
                    gnm = gnm + gdot[n, m] * dt_yr
                    hnm = hnm + hdot[n, m] * dt_yr
                c = gnm * cm[m] + hnm * sm[m]
                sr += c * P[m]
                stt += c * dP[m]
                if m > 0:
                    sp += m * (hnm * cm[m] - gnm * sm[m]) * P[m]
            Br += (n + 1) * rn * sr
            Bt -= rn * stt
            Bp -= rn * sp
        P_prev2, dP_prev2 = P_prev, dP_prev
        P_prev, dP_prev = P, dP
    Bp = Bp / st
    return Br, Bt, Bp


class GeomagField:
    """Geomagnetic reference field along an orbit, in GCI (ICD §2, §4).

    Parameters
    ----------
    epoch : mission epoch (datetime or ISO-8601 text).
    model : ``"igrf"`` (degrees 1..max_degree) or ``"dipole"`` (degree 1 only:
        the tilted, centred dipole of the same IGRF epoch).
    max_degree : highest degree for ``"igrf"`` (1..13; ICD §4 asks for 13).
    generation : IGRF generation, 13 or 14 (14 by default; valid 1900–2030).

    Attributes
    ----------
    years, g, h : the coefficient table in use (see :func:`load_igrf_coefficients`).
    valid_from, valid_to : decimal years the table covers.
    """

    def __init__(self, epoch, *, model: str = "igrf", max_degree: int = 13, generation: int = 14):
        self.epoch: datetime = timescale.parse_epoch(epoch)
        if model not in ("igrf", "dipole"):
            raise InputError(f"unknown geomagnetic model '{model}' (use 'igrf' or 'dipole')", key="geomag.model")
        self.model = model
        years, g, h = load_igrf_coefficients(generation)
        self.generation = int(generation)
        top = g.shape[1] - 1
        if not 1 <= int(max_degree) <= top:
            raise InputError(f"max_degree must be 1..{top}, got {max_degree}", key="geomag.max_degree")
        self.max_degree = 1 if model == "dipole" else int(max_degree)
        self.years, self.g, self.h = years, g, h
        self.valid_from, self.valid_to = float(years[0]), float(years[-1])
        # secular variation per interval [nT/yr]
        dy = np.diff(years)[:, None, None]
        self._gdot = np.diff(g, axis=0) / dy
        self._hdot = np.diff(h, axis=0) / dy

    def _check_dates(self, year):
        lo, hi = float(np.min(year)), float(np.max(year))
        if lo < self.valid_from or hi > self.valid_to:
            raise InputError(
                f"IGRF-{self.generation} covers {self.valid_from:.1f}–{self.valid_to:.1f}; "
                f"the requested times fall in {lo:.4f}–{hi:.4f} (decimal years). "
                f"Check the mission epoch.",
                key="mission.epoch",
            )

    def coefficients_at(self, year):
        """Gauss coefficients ``(g, h)`` at decimal year(s), ``(…, 14, 14)`` [nT]."""
        year = np.asarray(year, dtype=float)
        self._check_dates(year)
        k = np.clip(np.searchsorted(self.years, year, side="right") - 1, 0, self.years.size - 2)
        dt = (year - self.years[k])[..., None, None]
        return self.g[k] + dt * self._gdot[k], self.h[k] + dt * self._hdot[k]

    def field_E(self, year, r_E_km) -> np.ndarray:
        """Field [nT] in Earth-fixed axes at Earth-fixed positions (N, 3) for decimal years (N,)."""
        r_E = np.atleast_2d(np.asarray(r_E_km, dtype=float))
        year = np.broadcast_to(np.asarray(year, dtype=float), (r_E.shape[0],))
        self._check_dates(year)
        out = np.empty_like(r_E)
        for i0 in range(0, r_E.shape[0], _CHUNK):
            sl = slice(i0, i0 + _CHUNK)
            x, y, z = r_E[sl, 0], r_E[sl, 1], r_E[sl, 2]
            rho = np.hypot(x, y)
            r = np.hypot(rho, z)
            theta = np.arctan2(rho, z)
            phi = np.arctan2(y, x)
            yr = year[sl]
            # interval of the coefficient table holding each point (usually one per chunk)
            k = np.clip(np.searchsorted(self.years, yr, side="right") - 1, 0, self.years.size - 2)
            Br, Bt, Bp = np.empty_like(r), np.empty_like(r), np.empty_like(r)
            for kk in np.unique(k):
                sel = k == kk
                Br[sel], Bt[sel], Bp[sel] = spherical_harmonic_field(
                    r[sel],
                    theta[sel],
                    phi[sel],
                    self.g[kk],
                    self.h[kk],
                    max_degree=self.max_degree,
                    gdot=self._gdot[kk],
                    hdot=self._hdot[kk],
                    dt_yr=yr[sel] - self.years[kk],
                )
            ct, st = np.cos(theta), np.sin(theta)
            cp, sp = np.cos(phi), np.sin(phi)
            # B = B_r r_hat + B_θ θ_hat + B_φ φ_hat
            Bh = Br * st + Bt * ct  # component along (cos φ, sin φ, 0)
            out[sl, 0] = Bh * cp - Bp * sp
            out[sl, 1] = Bh * sp + Bp * cp
            out[sl, 2] = Br * ct - Bt * st
        return out

    def field_I(self, t, r_I_km) -> np.ndarray:
        """Field [nT] in GCI at mission times ``t`` (N,) and GCI positions ``r_I_km`` (N, 3).

        ``B_I = R3(GMST)ᵀ B_E(R3(GMST) r_I)`` (ICD §2). Raises :class:`InputError` when a
        time falls outside the coefficient table. Returns (N, 3).
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        r_I = np.atleast_2d(np.asarray(r_I_km, dtype=float))
        if r_I.shape != (t.size, 3):
            raise ValueError(f"r_I_km has shape {r_I.shape}, expected ({t.size}, 3)")
        year = timescale.decimal_year(self.epoch, t)
        self._check_dates(year)
        gmst = timescale.gmst_rad(self.epoch, t)
        c, s = np.cos(gmst), np.sin(gmst)
        # r_E = T3(gmst) r_I: x_E = c x + s y, y_E = -s x + c y
        r_E = np.column_stack([c * r_I[:, 0] + s * r_I[:, 1], -s * r_I[:, 0] + c * r_I[:, 1], r_I[:, 2]])
        B_E = self.field_E(year, r_E)
        # B_I = T3(gmst)^T B_E
        return np.column_stack([c * B_E[:, 0] - s * B_E[:, 1], s * B_E[:, 0] + c * B_E[:, 1], B_E[:, 2]])

    def field_magnitude(self, t, r_I_km) -> np.ndarray:
        """``|B|`` [nT] at mission times ``t`` and GCI positions (N,)."""
        return np.linalg.norm(self.field_I(t, r_I_km), axis=-1)
