"""First-order Gauss–Markov sensor noise, exact at the sample times.

A sensor whose key ``noise_correlation_s`` (truth or data book) is a correlation time
``τ > 0`` draws its additive noise as a stationary first-order Gauss–Markov process of
standard deviation ``σ`` (the sensor's ``noise``) per component instead of white noise.
Sampled at times ``t_k`` the process is exactly the AR(1) recursion (Gelb, *Applied
Optimal Estimation*, MIT Press 1974, §3.8; Maybeck, *Stochastic Models, Estimation and
Control* vol. 1, 1979, §4.10)::

    x_0 = σ w_0,    x_k = φ_k x_{k−1} + σ sqrt(1 − φ_k²) w_k,    φ_k = exp(−(t_k − t_{k−1}) / τ)

with ``w_k ~ N(0, 1)`` independent: its variance is ``σ²`` at every sample and its
autocorrelation ``exp(−|Δt|/τ)``, whatever the spacing (gaps included: the process runs
through them). The state is carried from one chunk of rows to the next, so the draws do
not depend on how the simulator chunks the span. ``σ`` may be split: ``noise_correlated``
(default: all of ``noise``) is the Gauss–Markov part, the rest of ``noise²`` is white.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["GaussMarkov", "correlated_noise"]


class GaussMarkov:
    """A stationary first-order Gauss–Markov process of ``dim`` independent components."""

    def __init__(self, tau_s: float, sigma: float, dim: int, rng: np.random.Generator):
        if not (tau_s > 0 and math.isfinite(tau_s)):
            raise ValueError(f"correlation time {tau_s!r} s must be positive")
        self.tau_s, self.sigma, self.dim, self.rng = float(tau_s), float(sigma), int(dim), rng
        self._t: float | None = None
        self._x = np.zeros(self.dim)

    def draw(self, t: np.ndarray) -> np.ndarray:
        """(n, dim) samples at the increasing times ``t`` [s] (module docstring)."""
        t = np.asarray(t, float)
        w = self.rng.standard_normal((t.size, self.dim))
        out = np.empty_like(w)
        x, t_prev = self._x, self._t
        for k in range(t.size):
            if t_prev is None:
                x = self.sigma * w[k]
            else:
                phi = math.exp(-max(t[k] - t_prev, 0.0) / self.tau_s)
                x = phi * x + self.sigma * math.sqrt(1.0 - phi * phi) * w[k]
            out[k] = x
            t_prev = float(t[k])
        self._x, self._t = x, t_prev
        return out


def correlated_noise(sensor, sigma: float, dim: int, rng: np.random.Generator):
    """The sensor's noise source: ``(white_sigma, GaussMarkov | None)``.

    Without ``noise_correlation_s`` it is white of ``sigma`` (None: the caller keeps its
    own white draw, so the white streams are unchanged); with it, the Gauss–Markov part of
    ``noise_correlated`` (default ``sigma``) and the white remainder."""
    tau = sensor.value("noise_correlation_s", None)
    if tau is None or not float(tau) > 0:
        return sigma, None
    sig_c = float(sensor.value("noise_correlated", None) or sigma)
    sig_c = min(sig_c, sigma)
    white = math.sqrt(max(sigma * sigma - sig_c * sig_c, 0.0))
    gm_rng = np.random.default_rng(rng.integers(2**62))
    return white, GaussMarkov(float(tau), sig_c, dim, gm_rng)


#: the sensor types whose simulators draw Gauss–Markov noise
CORRELATED_TYPES = ("star_tracker", "magnetometer")


def with_gauss_markov(cfg, tau_s: float, *, types=CORRELATED_TYPES, declared: bool = False):
    """``cfg`` with Gauss–Markov noise of correlation time ``tau_s`` [s] at the stated σ on
    every sensor of ``types``: in the truth only (a hidden property of the noise; the
    mission's data book says white), or, ``declared``, in the data book too (written to
    mission.toml as ``noise_correlation_s``). Returns ``cfg`` (changed in place)."""
    for s in cfg.sensors:
        if s.type in types:
            (s.book if declared else s.true)["noise_correlation_s"] = float(tau_s)
    return cfg
