"""Independent forward models of the seven ICD §5 sensor types, with TRUE parameters.

This module holds the magnetometer and the two digital Sun sensors (the factory for all
seven is :func:`gcs_core.sim.writer.make_sensor_sim`); the star tracker lives in :mod:`.stars`, the gyro
in :mod:`.truth`, the plane-field Sun sensor and horizon scanner in :mod:`.spinner`.
Every simulator has ``columns``, ``formats`` (printf formats of the CSV columns) and
``run(t_rows) -> {column: (N,) array}``; rows the sensor cannot produce (eclipse, Sun
outside the field of view, occultation) are simply absent.

A measurement stamped ``t`` is made at ``t' = t + time_offset_s`` (the hidden time-tag
offset; zero in the data book).

Noise (ICD ``noise``: 1-sigma per component, quantization included): for integer-count
sensors the Gaussian part is ``σ_g = sqrt(noise² − 1/12)`` before rounding to an integer,
so that Gaussian plus rounding has the data-book total; other sensors add ``N(0, noise²)``,
or, for the magnetometer and the star tracker with ``noise_correlation_s`` set, first-order
Gauss–Markov noise of that stationary σ (:mod:`gcs_core.sim.gauss_markov`).

Magnetometer (Eq 4-27), with the hidden response matrix ``K`` (scale and
non-orthogonality, ``I`` in the book) and contamination by auxiliary channels::

    B_S = K M C_BI(t') B_I(t') + b + Σ_ch k_ch a_ch(t') + n,   B_I from IGRF (field.py)

Sun direction, real physics by default (mission ``physics`` switches): seen from the
spacecraft, ``Ŝ = unit(s − r)`` (``sun_parallax``), then aberrated by the spacecraft's
geocentric velocity, ``Ŝ' = unit(Ŝ + v/c − (Ŝ·v/c) Ŝ)`` (``solar_aberration``; the
ephemeris Sun is already apparent for a geocentric observer). No Sun data in the Earth's
shadow (penumbra included, astro.py).

Fine Sun sensor (Eq 4-22 to 4-25), ``S_S = M C_BI Ŝ``, per axis (α shown), with the hidden
second harmonic ``H_α`` of the transfer function (0 in the book)::

    tan α = S_Sy / S_Sx
    n_α = round((tan α − A1 − A3 sin(k tan α) − H_α sin(2k tan α)) / A2 + N(0, σ_g²))

valid when ``S_Sx > 0`` and ``|α|, |β| ≤ fov_deg``.

Coarse Sun sensor (Eq 4-16, 4-17)::

    α = atan2(S_Sy, S_Sx),   n_α = round((α + b_α) / K_α + N(0, σ_g²))
"""

from __future__ import annotations

import numpy as np

from gcs_core.sim import astro, drifts
from gcs_core.sim._rot import rpy_to_dcm, unit
from gcs_core.sim.config import SensorConfig
from gcs_core.sim.field import igrf_gci
from gcs_core.sim.gauss_markov import correlated_noise

__all__ = ["MagnetometerSim", "FineSunSim", "CoarseSunSim", "sun_unit_from_sc"]


def _alignment(sensor: SensorConfig) -> np.ndarray:
    a = np.radians(np.asarray(sensor.value("alignment_deg", (0.0, 0.0, 0.0)), dtype=float))
    return rpy_to_dcm(a[0], a[1], a[2])


def count_sigma(noise: float) -> float:
    """Gaussian part of a total ``noise`` [counts] that also contains integer rounding."""
    return float(np.sqrt(max(noise**2 - 1.0 / 12.0, 0.0)))


def sun_unit_from_sc(r_I, v_I, s_I, *, parallax: bool = True, aberration: bool = True) -> np.ndarray:
    """Apparent unit Sun vector at the spacecraft, (N, 3); see the module docstring."""
    S = unit(np.asarray(s_I) - np.asarray(r_I)) if parallax else unit(np.asarray(s_I))
    if aberration:
        beta = np.asarray(v_I) / astro.C_KM_S
        d = np.einsum("ij,ij->i", S, beta)[:, None]
        S = unit(S + beta - d * S)
    return S


class MagnetometerSim:
    """TAM rows ``t, bx, by, bz`` [nT]."""

    columns = ("t", "bx", "by", "bz")
    formats = ("%.3f",) * 4

    def __init__(self, sensor: SensorConfig, world, rng: np.random.Generator, aux=None):
        self.s, self.world, self.rng, self.aux = sensor, world, rng, aux
        self.M = _alignment(sensor)
        self.K = np.asarray(sensor.value("response", np.eye(3)), dtype=float)
        self.bias = np.asarray(sensor.value("bias", (0.0, 0.0, 0.0)), dtype=float)
        self.noise = float(sensor.value("noise"))
        self.tau = float(sensor.value("time_offset_s", 0.0))
        self.contamination = {
            ch: np.asarray(k, dtype=float) for ch, k in dict(sensor.value("contamination", {}) or {}).items()
        }
        self.quantum = float(sensor.value("quantum", 0.0) or 0.0)
        self.white, self.gm = correlated_noise(sensor, self.noise, 3, rng)

    def run(self, t_rows: np.ndarray) -> dict[str, np.ndarray]:
        w = self.world
        tt = t_rows + self.tau
        r, v = w.orbit(tt)
        B_I = igrf_gci(w.epoch, w.jd0, tt, r)
        C = w.attitude(tt, r, v)
        B_S = np.einsum("ij,njk,nk->ni", self.K @ self.M, C, B_I)
        g = drifts.gains(self.s, self.aux, tt)
        if g is not None:  # gains drifting with a channel: (K + diag g) M C B_I
            B_S = B_S + g * np.einsum("ij,njk,nk->ni", self.M, C, B_I)
        B_S = B_S + self.bias
        for ch, k in self.contamination.items():
            B_S = B_S + self.aux.value(ch, tt)[:, None] * k[None, :]
        if self.gm is None:
            B_S = B_S + self.rng.standard_normal(B_S.shape) * self.noise
        else:  # Gauss–Markov noise (gauss_markov.py), exact at the sample times
            B_S = B_S + self.gm.draw(t_rows) + self.rng.standard_normal(B_S.shape) * self.white
        if self.quantum > 0:
            B_S = np.round(B_S / self.quantum) * self.quantum
        return {"t": t_rows, "bx": B_S[:, 0], "by": B_S[:, 1], "bz": B_S[:, 2]}


class _SunSim:
    columns = ("t", "n_alpha", "n_beta")
    formats = ("%.12g", "%d", "%d")

    def __init__(self, sensor: SensorConfig, world, rng: np.random.Generator):
        self.s, self.world, self.rng = sensor, world, rng
        self.M = _alignment(sensor)
        self.fov = np.radians(float(sensor.value("fov_deg")))
        self.sig_g = count_sigma(float(sensor.value("noise")))
        self.tau = float(sensor.value("time_offset_s", 0.0))
        ph = world.cfg.physics
        self.aberration = bool(ph.get("solar_aberration", True))
        self.parallax = bool(ph.get("sun_parallax", True))
        self.n_eclipsed = 0
        self.aux = None  # the mission's aux channels (a drifting offset follows one; drifts.py)

    def sun_sensor_frame(self, t_rows):
        w = self.world
        tt = t_rows + self.tau
        r, v = w.orbit(tt)
        s = w.sun(tt)
        S_I = sun_unit_from_sc(r, v, s, parallax=self.parallax, aberration=self.aberration)
        S_S = np.einsum("ij,njk,nk->ni", self.M, w.attitude(tt, r, v, s), S_I)
        lit = ~astro.sun_eclipsed(r, s)
        self.n_eclipsed += int(np.sum(~lit))
        return S_S, lit

    def _finish(self, t_rows, keep, x_a, x_b):
        # one (N, 2) draw per chunk: the stream is consumed row by row, whatever the chunking
        n = np.round(np.stack([x_a, x_b], -1) + self.rng.standard_normal((x_a.size, 2)) * self.sig_g)
        return {"t": t_rows[keep], "n_alpha": n[keep, 0], "n_beta": n[keep, 1]}


class FineSunSim(_SunSim):
    """FSS rows ``t, n_alpha, n_beta`` [counts] (Eq 4-23 inverted)."""

    def run(self, t_rows: np.ndarray) -> dict[str, np.ndarray]:
        S_S, lit = self.sun_sensor_frame(t_rows)
        ta = S_S[:, 1] / S_S[:, 0]
        tb = S_S[:, 2] / S_S[:, 0]
        keep = lit & (S_S[:, 0] > 0) & (np.abs(np.arctan(ta)) <= self.fov) & (np.abs(np.arctan(tb)) <= self.fov)
        A1, A2, A3, ka = (float(x) for x in self.s.value("coeff_alpha"))
        B1, B2, B3, kb = (float(x) for x in self.s.value("coeff_beta"))
        Ha, Hb = (float(x) for x in self.s.value("harmonic", (0.0, 0.0)))
        dA1, dB1 = drifts.offsets(self.s, self.aux, t_rows + self.tau)
        xa = (ta - (A1 + dA1) - A3 * np.sin(ka * ta) - Ha * np.sin(2 * ka * ta)) / A2
        xb = (tb - (B1 + dB1) - B3 * np.sin(kb * tb) - Hb * np.sin(2 * kb * tb)) / B2
        return self._finish(t_rows, keep, xa, xb)


class CoarseSunSim(_SunSim):
    """CSS rows ``t, n_alpha, n_beta`` [counts] (Eq 4-16, 4-17)."""

    def run(self, t_rows: np.ndarray) -> dict[str, np.ndarray]:
        S_S, lit = self.sun_sensor_frame(t_rows)
        a = np.arctan2(S_S[:, 1], S_S[:, 0])
        b = np.arctan2(S_S[:, 2], S_S[:, 0])
        keep = lit & (S_S[:, 0] > 0) & (np.abs(a) <= self.fov) & (np.abs(b) <= self.fov)
        K = np.asarray(self.s.value("scale"), dtype=float)
        bias = np.asarray(self.s.value("bias", (0.0, 0.0)), dtype=float)
        return self._finish(t_rows, keep, (a + bias[0]) / K[0], (b + bias[1]) / K[1])
