"""Honest σ under correlated residuals: a per-element σ scale from the residuals themselves.

The fit's covariance assumes each sensor's errors white with the stated σ. Real residuals
are often correlated over the time scale on which the parameters are determined (a hand
turning a unit every few seconds; a room's field; an optical reference interpolated
between its camera frames), and then the σ are optimistic by a factor no white-noise
statistic shows. The batch-means sandwich ("heteroskedasticity and autocorrelation
consistent" covariance; Newey & West, Econometrica 55(3), 1987, 703–708; the batch-means
form: Conway, Operations Research 11(1), 1963) measures it from the data:

    A = Σ_k H_kᵀ R⁻¹ H_k + P₀⁻¹            (the information the fit assumed, a priori included)
    g_b = Σ_{k ∈ b} H_kᵀ R⁻¹ r_k           (the score of block b: frames in one window of L s)
    B = Σ_b g_b g_bᵀ + P₀⁻¹                 (what the residuals actually supply, and the a priori)
    Cov_honest = A⁻¹ B A⁻¹,    s_i = sqrt((A⁻¹ B A⁻¹)_ii / (A⁻¹)_ii)

over the solve-for elements other than the attitude's (a sensor's own, the shared ones such
as ``field.*``, and the gyro's, which the gyro-carried attitude passes to every sensor),
with the scores of all the measurement sensors summed within each window (errors common to
two sensors in one window count once, as they should), conditional on the attitude. The a
priori is one more observation, with its own white error, so it enters ``B`` as it enters
``A``: with white residuals of the stated σ ``E[B] = A`` and ``s ≈ 1``; residuals correlated
over windows shorter than ``L`` raise ``B`` by exactly the factor that inflates the
estimate's scatter, and an element whose variance the a priori sets (a field's magnitude
beside a magnetometer's scale factors) is not inflated by them. ``A`` is inverted scaled to a
unit diagonal (:func:`equilibrated_inverse`): it spans nT and rad, and a plain
pseudo-inverse's relative cut dropped or kept the a priori's directions with the round-off.
``s_i`` multiplies the fit's σ of element ``i``. The window ``L`` must exceed the
residual's correlation time and leave many windows in the span: the estimate of each
``s_i²`` has about ``n_b`` (number of windows) degrees of freedom, so ``s`` itself scatters
by about ``1/sqrt(2 n_b)``.

Conditional on the attitude. ``A`` is the information with the attitude held; the fit's
own covariance has the attitude (and, for the whole-span method, its knots) marginalized.
For an element the attitude cannot absorb — a ground calibration under a precise attitude
reference, the BROAD magnetometer against a reference 30 times finer than it — the two
agree and ``s`` is the honest factor (``tests/statistical/test_sigma_scale.py``). For an element the
attitude's freedom absorbs in part (a Sun sensor's or a gyro's in flight, against knots
every tens of seconds) the residuals are orthogonal to what the attitude took, window by
window, and ``s`` comes out below 1 on a correct model (0.3–0.9 on the 8-h Sun-pointing
example): that is the method's blind spot, not better data, so
:meth:`SigmaScale.honest_sigma` never scales a σ down.

Residuals are the fit's own (``result.residuals``, knots included for the whole-span
method); the partials are those of the sensor's model at the fitted state.

:func:`noise_scale` is the same batch-means ratio for one sensor's residuals alone, with no
partials: the factor by which its stated σ understates its effective white noise on time
scales longer than its correlation, for weighting a reference whose errors are correlated
(an optical attitude in motion) against a gyro that carries the attitude across them.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from gcs_core.errors import InputError
from gcs_core.problem.linearization import iter_blocks
from gcs_core.problem.state import prior_information

log = logging.getLogger(__name__)

#: default window [s]: several times the hand motions' time scale on the BROAD trials
BLOCK_S = 4.0
#: fewer windows than this: the scale is not estimated (its own scatter exceeds ~16 %)
MIN_BLOCKS = 20
#: a scale above this (or not finite) is a numerical failure of the sandwich, not a finding
SCALE_MAX = 1e3
#: relative cut of the equilibrated information's pseudo-inverse (when not positive definite)
PINV_RCOND = 1e-12


@dataclass(frozen=True)
class SigmaScale:
    """σ scales of the solve-for elements.

    Attributes
    ----------
    sensors : the sensors whose residuals entered; block_s : window [s]; n_blocks :
        windows holding used frames.
    scale : element -> ``s_i`` (module docstring); multiply the fit's σ by it.
    failed : elements whose scale was not finite or above :data:`SCALE_MAX` (a numerical
        failure of the sandwich, guarded: left out of ``scale`` and reported).
    """

    sensors: tuple[str, ...]
    block_s: float
    n_blocks: int
    scale: Mapping[str, float]
    failed: tuple[str, ...] = ()

    def honest_sigma(self, sigma: Mapping[str, float]) -> dict[str, float]:
        """``σ_i max(1, s_i)`` (elements without a scale unchanged; a scale below 1 is the
        conditional sandwich's blind spot, module docstring, and never shrinks a σ)."""
        return {n: float(s * max(1.0, self.scale.get(n, 1.0))) for n, s in sigma.items()}


def sigma_scale(problem, result, sensors=None, *, block_s: float = BLOCK_S) -> SigmaScale:
    """The batch-means sandwich σ scale of the solve-for elements (module docstring).

    Parameters
    ----------
    problem : the fitted :class:`~gcs_core.problem.build.Problem`.
    result : its fit result (``state``, ``solve_for``, ``residuals``).
    sensors : measurement sensor names (default: every sensor with residuals).
    block_s : window length [s], > 0.

    Raises
    ------
    InputError : an unknown sensor, a window that is not positive, or fewer than
        :data:`MIN_BLOCKS` windows with used frames.
    """

    if not (np.isfinite(block_s) and block_s > 0):
        raise InputError(f"window {block_s!r} s must be a positive number", key="block_s")
    sensors = tuple(result.residuals) if sensors is None else tuple(sensors)
    for name in sensors:
        if name not in result.residuals:
            raise InputError(f"no residuals of sensor '{name}' (known: {', '.join(result.residuals)})", key="sensor")
    state = result.state
    values = state.values()
    columns = [n for n in result.solve_for if state[n].kind != "attitude"]
    t0 = min(float(result.residuals[n].t[0]) for n in sensors)
    bins, r_w, used = {}, {}, {}
    for name in sensors:
        res = result.residuals[name]
        bins[name] = np.floor((np.asarray(res.t, float) - t0) / block_s).astype(np.int64)
        used[name] = np.asarray(res.used, bool)
        r_w[name] = np.where(used[name][:, None], np.asarray(res.residual, float), 0.0) / np.asarray(res.sigma, float)
    n_bins = max(int(b.max()) for b in bins.values()) + 1
    k = len(columns)
    A = np.zeros((k, k))
    G = np.zeros((n_bins, k))
    touched = np.zeros(k, bool)
    for blk in iter_blocks(
        problem, values, columns, weighted=True, sensors=list(sensors), exclude={n: ~used[n] for n in sensors}
    ):
        if blk.H is None or not blk.cols.size:
            continue
        H, c = blk.H, blk.cols  # (n, m, k_s): R^-1/2 H, unused rows 0
        Hf = H.reshape(-1, c.size)
        A[np.ix_(c, c)] += Hf.T @ Hf
        sc = np.einsum("nmk,nm->nk", H, r_w[blk.name][blk.lo : blk.hi])
        np.add.at(G, (bins[blk.name][blk.lo : blk.hi][:, None], c[None, :]), sc)
        touched[c] = True
    names = [n for n, hit in zip(columns, touched) if hit]
    idx = np.flatnonzero(touched)
    n_blocks = int(np.unique(np.concatenate([bins[n][used[n]] for n in sensors])).size)
    if n_blocks < MIN_BLOCKS:
        raise InputError(
            f"{n_blocks} windows of {block_s:g} s hold used frames; at least {MIN_BLOCKS} are needed for a σ scale",
            key="block_s",
        )
    prior = prior_information(state, names)  # P₀⁻¹ (diagonal)
    A = A[np.ix_(idx, idx)] + prior
    G = G[:, idx]
    # inverted scaled to a unit diagonal (module docstring): a plain pseudo-inverse kept
    # or dropped the a priori's directions with the round-off (a TAM bias's scale moved ×2
    # with the summation order of the normal equations)
    d = np.sqrt(np.maximum(np.diag(A), 1e-300))
    Ainv = equilibrated_inverse(A / np.outer(d, d)) / np.outer(d, d)
    with np.errstate(all="ignore"):
        honest = np.einsum("ij,jk,ki->i", Ainv, G.T @ G + prior, Ainv)
        scale = np.sqrt(np.maximum(honest, 0.0) / np.maximum(np.diag(Ainv), 1e-300))
    # where A is not positive definite its pseudo-inverse can keep a direction it should have
    # cut, and the scale explodes (issue 27: TAM1.bias_y at 1.6e130): not a finding
    ok = np.isfinite(scale) & (scale < SCALE_MAX) & (np.diag(Ainv) > 0)
    failed = tuple(n for n, good in zip(names, ok) if not good)
    if failed:
        # the report and the σ-scale block name them; not a warning of the fit (no TUI notice)
        log.info("σ scale not estimable (numerically) for %s: left out", ", ".join(failed))
    kept = {n: float(x) for n, x, good in zip(names, scale, ok) if good}
    return SigmaScale(sensors, float(block_s), n_blocks, kept, failed)


def equilibrated_inverse(As: np.ndarray) -> np.ndarray:
    """Inverse of an information matrix scaled to a unit diagonal: the exact inverse when
    it is positive definite (a direction only the a priori sets is kept, however small its
    eigenvalue), else the pseudo-inverse at :data:`PINV_RCOND`."""
    try:
        c = np.linalg.cholesky(As)
        ci = np.linalg.inv(c)
        return ci.T @ ci
    except np.linalg.LinAlgError:
        return np.linalg.pinv(As, rcond=PINV_RCOND, hermitian=True)


def noise_scale(result, sensor: str, *, block_s: float) -> float:
    """The long-run noise factor of one sensor's residuals: how much larger its stated σ
    would have to be for white noise to carry the information its residuals carry over
    windows of ``block_s``::

        s² = Σ_b ‖Σ_{k ∈ b} r_k / σ_k‖² / Σ_k ‖r_k / σ_k‖²

    (the batch-means estimate of ``1 + 2 Σ_j ρ_j``, the long-run over the short-run
    variance; Conway 1963). White residuals give ``s ≈ 1``; residuals held over ``n``
    samples ``s ≈ √n``. ``σ s`` is the sensor's effective white noise on time scales longer
    than its correlation time, which is what weights it honestly against a gyro that
    carries the attitude across those scales. Residuals are the fit's own; what a fit's
    dynamic freedom absorbed is not in them, so ``s`` is a lower bound.

    Raises InputError for an unknown sensor or a window that is not positive.
    """
    if not (np.isfinite(block_s) and block_s > 0):
        raise InputError(f"window {block_s!r} s must be a positive number", key="block_s")
    if sensor not in result.residuals:
        raise InputError(f"no residuals of sensor '{sensor}' (known: {', '.join(result.residuals)})", key="sensor")
    res = result.residuals[sensor]
    t = np.asarray(res.t, float)
    used = np.asarray(res.used, bool)
    w = np.where(used[:, None], np.asarray(res.residual, float) / np.asarray(res.sigma, float), 0.0)
    bins = np.floor((t - t[0]) / block_s).astype(np.int64)
    sums = np.zeros((int(bins.max()) + 1, w.shape[1]))
    np.add.at(sums, bins, w)
    return float(np.sqrt(np.sum(sums**2) / max(float(np.sum(w**2)), 1e-300)))
