"""The per-epoch read-out errors ``ε̂_k`` the whole-span fit linearizes about (the model and
the elimination: :mod:`gcs_core.estimators.whole_span.readout`).

:class:`EpochErrors` holds the epochs (every data time), the current linearization values
and their conditional optimum after a pass, and the sensitivities a pass records so that a
Gauss–Newton step's read-out part can be predicted (:meth:`EpochErrors.predicted`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_core.compiled import COMPILED
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.readout_kernels import _epoch_step
from gcs_core.problem.view_cache import ViewCache


def inverse_spd3(M: np.ndarray) -> np.ndarray:
    """(E, 3, 3) inverses of symmetric positive definite 3 × 3 matrices (adjugate over the
    determinant; here ``M = σ_e⁻² I + F``, conditioned by ``1 + σ_e² λ_max(F)``)."""
    a, b, c = M[:, 0, 0], M[:, 0, 1], M[:, 0, 2]
    d, e, f = M[:, 1, 1], M[:, 1, 2], M[:, 2, 2]
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    out = np.empty_like(M)
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = A, B, C
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = B, a * f - c * c, b * c - a * e
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = C, b * c - a * e, a * d - b * b
    out /= (a * A + b * B + c * C)[:, None, None]
    return out


def _sorted_union(ts: list[np.ndarray]) -> np.ndarray:
    """The sorted distinct times of several arrays (``numpy.unique`` of their
    concatenation; each sensor's times are in order, so a stable sort merges runs)."""
    if not ts:
        return np.zeros(0)
    T = np.concatenate(ts)
    T.sort(kind="stable")
    return T[np.r_[True, T[1:] != T[:-1]]] if T.size else T


#: the per-epoch sensitivities :meth:`EpochErrors.predicted` needs are kept below this size
#: [bytes] (G_x in single precision: a day of 1 Hz epochs over 31 statics is 45 MB)
PREDICT_BYTES = 256 * 2**20


@dataclass
class Sensitivities:
    """What a recording pass keeps per epoch for :meth:`EpochErrors.predicted`: ``Gx``
    (E, 3, p) ``D̃ᵀH̃`` in single precision, ``F`` and ``FC`` (E, 3, 3), ``base`` (E, 3) the
    conditional optimum there, ``have`` (E,) which epochs the pass reached."""

    Gx: np.ndarray
    F: np.ndarray
    FC: np.ndarray
    base: np.ndarray
    have: np.ndarray

    @classmethod
    def empty(cls, E: int, p: int) -> Sensitivities:
        return cls(
            np.empty((E, 3, p), np.float32),
            np.empty((E, 3, 3)),
            np.empty((E, 3, 3)),
            np.empty((E, 3)),
            np.zeros(E, bool),
        )


class EpochErrors:
    """The per-epoch read-out errors ``ε̂_k`` the whole-span fit linearizes about.

    T : (E,) the epochs (every sample time of the data); eps : (E, 3) the current
    linearization values [rad, body frame]; cond : (E, 3) their conditional optimum
    ``ε + M⁻¹ g_ε`` given the statics and knots of the last pass (:meth:`adopt` takes it).
    """

    def __init__(self, sensors):
        ts = [np.asarray(sd.t, float) for sd in sensors if sd.n]
        self.T = _sorted_union(ts)
        self.eps = np.zeros((self.T.size, 3))
        self.cond = self.eps.copy()
        self.stale = False  # ε̂ adopted after the last pass
        self.nonzero = False  # any ε̂ ≠ 0 (kept with ``eps``: asked per block)
        # the last recording pass's per-epoch sensitivities (:meth:`record_start`)
        self.sens: Sensitivities | None = None
        self.seeded = False  # ``cond`` from :func:`.readout.seed_errors`, not yet taken by the fit
        # (index, is an epoch) of times that view a sensor's frame times, asked at every pass
        self._where = ViewCache(4096)

    def index(self, t: np.ndarray) -> np.ndarray:
        """(n,) epoch of each time (every data time is one)."""
        return self._locate(t)[0]

    def _locate(
        self, t: np.ndarray, of: np.ndarray | None = None, tag: str = ""
    ) -> tuple[np.ndarray, np.ndarray | bool]:
        """(epoch index, whether the time is that epoch) of each time, kept when the times
        (or ``of``, the times they derive from, with a ``tag`` saying how) view a longer
        array (:class:`~gcs_core.problem.view_cache.ViewCache`)."""
        t = np.asarray(t, float)
        return self._where.get(t if of is None else of, tag, lambda: self._find(t))

    def _find(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray | bool]:
        i = np.clip(np.searchsorted(self.T, t), 0, max(self.T.size - 1, 0))
        hit = self.T[i] == t if self.T.size else np.zeros(np.shape(t), bool)
        return i, (True if np.all(hit) else hit)  # True: every time an epoch

    def at(self, t: np.ndarray, of: np.ndarray | None = None, tag: str = "") -> np.ndarray:
        """(n, 3) ε̂ at times ``t`` (0 at a time that is no epoch); ``of``, ``tag``: the
        times ``t`` derive from, for the cache (:meth:`_locate`)."""
        if not self.T.size:
            return np.zeros((np.size(t), 3))
        i, hit = self._locate(t, of, tag)
        if isinstance(hit, bool):  # True: every time is an epoch (_locate)
            return self.eps[i]
        return np.where(hit[:, None], self.eps[i], 0.0)

    def record_start(self, p: int) -> None:
        """Keep the next pass's per-epoch sensitivities (:meth:`predicted`) over ``p``
        static columns, unless they would exceed :data:`PREDICT_BYTES`."""
        E = self.T.size
        if not E or E * (3 * p * 4 + 21 * 8) > PREDICT_BYTES:
            self.sens = None
            return
        if self.sens is None or self.sens.Gx.shape != (E, 3, p):
            self.sens = Sensitivities.empty(E, p)
        self.sens.have.fill(False)

    def record(self, k: np.ndarray, Gx: np.ndarray, F: np.ndarray, FC: np.ndarray, cond: np.ndarray) -> None:
        """The epochs ``k``'s ``G_x = D̃ᵀH̃`` (E, 3, p), ``F``, ``F C`` and conditional optimum
        at the recording pass."""
        s = self.sens
        if s is None or not k.size:
            return
        at: slice | np.ndarray = k
        if k[-1] - k[0] + 1 == k.size:  # a window's epochs are a range (no epoch dropped)
            at = slice(int(k[0]), int(k[-1]) + 1)
        s.Gx[at], s.F[at], s.FC[at], s.base[at] = Gx, F, FC, cond
        s.have[at] = True

    def predicted(self, dx: np.ndarray, dz: np.ndarray, grid, R: np.ndarray, inv_e2: float) -> np.ndarray | None:
        """(E, 3) the read-out errors' part of the joint Gauss–Newton step taken from the
        recorded pass's point: ``ε̂ + M⁻¹(g_ε − G_x dx − F C α(dz))``, with ``α(dz)`` the
        knots' step at the epoch (:func:`~.knots.alpha_at`); the conditional optimum at
        the new statics and knots to first order. None when nothing was recorded."""
        s = self.sens
        if s is None or not np.any(s.have):
            return None
        k = slice(None) if s.have.all() else np.flatnonzero(s.have)
        Gx = s.Gx[k]
        a = kn.alpha_at(grid, dz, R, self.T[k])
        Gdx = (Gx.reshape(-1, Gx.shape[2]) @ dx.astype(np.float32)).reshape(-1, 3).astype(float)
        out = self.eps.copy()
        if COMPILED:
            step = np.empty_like(Gdx)
            _epoch_step(s.F[k], s.FC[k], Gdx, a, s.base[k], inv_e2, step)
            out[k] = step
            return out
        Minv = inverse_spd3(s.F[k] + inv_e2 * np.eye(3))
        out[k] = s.base[k] - np.einsum("eab,eb->ea", Minv, Gdx + np.einsum("eab,eb->ea", s.FC[k], a))
        return out

    def move_to(self, eps: np.ndarray) -> None:
        """Linearize the next passes about ``eps`` (the joint step's, :meth:`predicted`, or
        the one before it)."""
        self.eps = eps
        self.nonzero = bool(np.any(eps))
        self.stale = True

    def moved(self, sig_e: float) -> float:
        """The largest change :meth:`adopt` would make, in σ_e (inf when ε̂ changed since the
        last pass: that pass's normal equations are not at ε̂)."""
        if self.stale:
            return float("inf")
        return float(np.max(np.abs(self.cond - self.eps))) / sig_e if self.T.size else 0.0

    def adopt(self) -> None:
        """Linearize the next passes about the last pass's conditional optimum."""
        if not self.stale:
            self.eps = self.cond.copy()
            self.nonzero = bool(np.any(self.eps))
            self.stale = True
