"""A first-order Gauss–Markov noise declared as a PSD level: the exact conversion to its σ.

A flight data book may give a sensor's correlated noise not as its stationary σ but as a
spectral density. For the first-order Gauss–Markov process of correlation time ``τ``
(Gelb, *Applied Optimal Estimation*, MIT Press 1974, §3.8 and Table 3.8-1; Maybeck,
*Stochastic Models, Estimation and Control* vol. 1, 1979, §4.10)::

    dx/dt = −x/τ + w,    E[w(t) w(t')] = q δ(t − t')          (the shaping filter)
    E[x(t) x(t + Δ)] = σ_c² exp(−|Δ|/τ),    σ_c² = q τ / 2
    S(f) = 2 σ_c² τ / (1 + (2π f τ)²)      two-sided [u²/Hz], ∫_{−∞}^{∞} S df = σ_c²
    S₁(f) = 2 S(f) = 4 σ_c² τ / (1 + (2π f τ)²)               one-sided, f ≥ 0

(``u`` the sensor's telemetry unit). Two data-book forms are read, each with ``τ``
(``noise_correlation_s``):

* ``noise_correlated_density``: ``√q`` [u/√s], the density of the white noise driving the
  process: ``σ_c = √q · sqrt(τ/2)``;
* ``noise_correlated_psd``: the *one-sided* PSD level ``S₁(0)`` [u²/Hz] at frequencies well
  below the corner ``1/(2π τ)`` (the plateau of a measured spectrum): ``σ_c = sqrt(S₁(0) / (4 τ))``
  (a two-sided level is half of it: declare twice the two-sided value).

Both are exact for the process above; the result is the ``noise_correlated`` σ the rest of
GCS reads (:mod:`gcs_core.noise.correlated`, :mod:`gcs_core.sim.gauss_markov`).
"""

from __future__ import annotations

import math

#: data-book key -> (its unit given the telemetry unit ``u``, what it is)
PSD_KEYS = {
    "noise_correlated_density": ("u/sqrt(s)", "density √q of the white noise driving the Gauss–Markov part"),
    "noise_correlated_psd": ("u^2/Hz", "one-sided PSD level of the Gauss–Markov part below its corner 1/(2π τ)"),
}


def sigma_from_driving_density(density: float, tau_s: float) -> float:
    """``σ_c = √q · sqrt(τ/2)`` [u] from the driving-noise density ``√q`` [u/√s] and ``τ`` [s]."""
    return float(density) * math.sqrt(float(tau_s) / 2.0)


def sigma_from_psd_level(psd_one_sided: float, tau_s: float) -> float:
    """``σ_c = sqrt(S₁(0) / (4 τ))`` [u] from the one-sided low-frequency PSD level ``S₁(0)``
    [u²/Hz] and ``τ`` [s]."""
    return math.sqrt(float(psd_one_sided) / (4.0 * float(tau_s)))


def correlated_sigma(key: str, value: float, tau_s: float) -> float:
    """``σ_c`` [u] of the Gauss–Markov part declared by ``key`` (one of :data:`PSD_KEYS`)."""
    if key == "noise_correlated_density":
        return sigma_from_driving_density(value, tau_s)
    if key == "noise_correlated_psd":
        return sigma_from_psd_level(value, tau_s)
    raise KeyError(key)
