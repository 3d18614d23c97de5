"""Two-body orbit with the secular J2 drift, evaluated analytically at any time.

The truth orbit is a Keplerian ellipse whose node, perigee and mean anomaly drift at
the first-order secular J2 rates (Vallado 4th ed., Eq 9-41; Brouwer 1959), with
``p = a (1 − e²)`` and ``n = sqrt(μ / a³)``::

    dΩ/dt = −(3/2) n J2 (R_E/p)² cos i
    dω/dt =  (3/4) n J2 (R_E/p)² (5 cos² i − 1)
    dM/dt =  n [1 + (3/4) J2 (R_E/p)² sqrt(1 − e²) (3 cos² i − 1)]

Position ``r = R3(Ω) R1(i) R3(ω) p(M)`` (active rotations, perifocal ``p``) and the
velocity written to the ephemeris is the exact time derivative of that function,
including the drift terms::

    v = Ω̇ ẑ × r + R3(Ω) R1(i) [ω̇ ẑ × R3(ω) p + R3(ω) (dp/dM) Ṁ]

so that the cubic Hermite interpolation GCS applies between ephemeris rows (ICD §4)
reproduces the truth to centimetres. Being closed-form, the orbit can be evaluated at
arbitrary times (horizon crossings, time-tag offsets) at no cost and in any chunking.

References
----------
Vallado, D. A., *Fundamentals of Astrodynamics and Applications*, 4th ed., §9.6.
"""

from __future__ import annotations

import numpy as np

MU_EARTH = 398600.4418  # km^3/s^2
J2 = 1.08262668e-3
R_EQ_KM = 6378.137

__all__ = ["propagate", "secular_rates", "period_s"]


def secular_rates(a_km: float, e: float, i_rad: float) -> tuple[float, float, float]:
    """``(dΩ/dt, dω/dt, dM/dt)`` [rad/s] for mean elements ``a, e, i``."""
    n = np.sqrt(MU_EARTH / a_km**3)
    p = a_km * (1.0 - e * e)
    k = J2 * (R_EQ_KM / p) ** 2
    ci = np.cos(i_rad)
    raan_dot = -1.5 * n * k * ci
    argp_dot = 0.75 * n * k * (5.0 * ci * ci - 1.0)
    m_dot = n * (1.0 + 0.75 * k * np.sqrt(1.0 - e * e) * (3.0 * ci * ci - 1.0))
    return float(raan_dot), float(argp_dot), float(m_dot)


def period_s(a_km: float) -> float:
    """Keplerian period ``2π sqrt(a³/μ)`` [s]."""
    return float(2.0 * np.pi * np.sqrt(a_km**3 / MU_EARTH))


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def propagate(elements, t) -> tuple[np.ndarray, np.ndarray]:
    """Position [km] and velocity [km/s] in GCI at mission times ``t`` (N,).

    ``elements`` has ``a_km, e, i_deg, raan_deg, argp_deg, mean_anomaly_deg`` (mean
    elements at the epoch). Returns two (N, 3) arrays.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    a, e = elements.a_km, elements.e
    inc = np.radians(elements.i_deg)
    raan_dot, argp_dot, m_dot = secular_rates(a, e, inc)
    raan = np.radians(elements.raan_deg) + raan_dot * t
    argp = np.radians(elements.argp_deg) + argp_dot * t
    M = np.mod(np.radians(elements.mean_anomaly_deg) + m_dot * t, 2 * np.pi)
    E = M + e * np.sin(M)
    for _ in range(30):  # Newton on Kepler's equation E − e sin E = M
        dE = (E - e * np.sin(E) - M) / (1.0 - e * np.cos(E))
        E = E - dE
        if np.max(np.abs(dE)) < 1e-14:
            break
    cE, sE = np.cos(E), np.sin(E)
    b = np.sqrt(1.0 - e * e)
    zero = np.zeros_like(E)
    p = a * np.stack([cE - e, b * sE, zero], -1)  # perifocal position
    dp_dM = a * np.stack([-sE, b * cE, zero], -1) / (1.0 - e * cE)[:, None]
    R_w = _rz(argp)
    R_O = _rz(raan)
    R_i = _rx(inc)
    p_w = np.einsum("nij,nj->ni", R_w, p)
    inner = argp_dot * np.stack([-p_w[:, 1], p_w[:, 0], zero], -1) + np.einsum("nij,nj->ni", R_w, dp_dM) * m_dot
    q = p_w @ R_i.T
    r = np.einsum("nij,nj->ni", R_O, q)
    v = np.einsum("nij,nj->ni", R_O, inner @ R_i.T)
    v = v + raan_dot * np.stack([-r[:, 1], r[:, 0], zero], -1)
    return r, v
