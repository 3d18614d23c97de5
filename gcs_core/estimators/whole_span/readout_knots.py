"""The read-out elimination's downdate of the knot blocks (:mod:`gcs_core.estimators.whole_span.readout`).

Eliminating each epoch's read-out error ``ε_k`` removes, from the knots' normal blocks, the
information its three pseudo-rows carried: per epoch ``U_lᵀ U_r`` from the knot block and
``U_lᵀ Y`` from its coupling to the statics and the residual, with the knot rows
``U = D [I | Γ_j(t)]`` of :func:`~gcs_core.estimators.whole_span.knots.knot_rows`.
:func:`subtract_knot_rows` takes ``M⁻¹`` whole; :func:`subtract_factored_knot_rows` the
Cholesky-factored form the compiled path keeps.
"""

from __future__ import annotations

import numpy as np

from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.readout_kernels import _epoch_knot_rows


def subtract_knot_rows(sysk: kn.KnotSystem, Dl: np.ndarray, Dr: np.ndarray, t: np.ndarray, Y: np.ndarray, cols) -> None:
    """Subtract the epochs' downdate from the knot blocks of ``sysk`` (module docstring):
    per epoch (E of them, times ``t`` in order) ``Dk_j −= U_lᵀ U_r`` and
    ``Bk_j −= U_lᵀ Y`` with ``U_l = Dl [I | Γ_j(t)]``, ``U_r = Dr [I | Γ_j(t)]``: ``Dl = F C``,
    ``Dr = M⁻¹ F C`` (E, 3, 3), ``Y = M⁻¹ G`` (E, 3, p + 1) over ``cols`` (p,) and the
    residual column."""
    if not t.size:
        return
    j = sysk.grid.index(t)
    eye = np.broadcast_to(np.eye(3), (t.size, 3, 3))
    Ul = kn.knot_rows(Dl, eye, t, j, sysk.grid, sysk.R)  # (E, 3, d)
    Ur = kn.knot_rows(Dr, eye, t, j, sysk.grid, sysk.R)
    knot = sysk._local(j.astype(np.int64))
    starts = np.flatnonzero(np.r_[True, knot[1:] != knot[:-1]])
    js = knot[starts]
    Ult = np.swapaxes(Ul, 1, 2)
    DD = np.add.reduceat(np.matmul(Ult, Ur), starts, axis=0)
    sysk.Dk[js] -= 0.5 * (DD + np.swapaxes(DD, 1, 2))
    HB = np.add.reduceat(np.matmul(Ult, Y), starts, axis=0)  # (J, d, p + 1)
    cols = np.asarray(cols, int)
    if cols.size:
        Bk = sysk.Bk
        for q, c in enumerate(cols):
            Bk[js, :, c] -= HB[:, :, q]
    sysk.Bk[js, :, -1] -= HB[:, :, -1]


def subtract_factored_knot_rows(sysk: kn.KnotSystem, W: np.ndarray, t: np.ndarray, V: np.ndarray, cols) -> None:
    """:func:`subtract_knot_rows` from the factored epochs: with ``M = L Lᵀ`` per epoch,
    ``W = L⁻¹ F C`` (E, 3, 3) and ``V = L⁻¹ G`` (E, 3, p + 1) the downdate is
    ``Dk_j −= Uᵀ U``, ``Bk_j −= Uᵀ V`` with ``U = W [I | Γ_j(t)]`` (``U_lᵀ U_r = Uᵀ U``,
    ``U_lᵀ Y = Uᵀ V``): the rows formed compiled, the sums one BLAS product per knot."""
    if not t.size:
        return
    j = sysk.grid.index(t).astype(np.int64)
    R, d = sysk.R, sysk.grid.d
    U = np.empty((t.size, 3, d))
    _epoch_knot_rows(W, t, j, sysk.grid.tau, R if R.shape[0] else np.zeros((1, 3, 3)), U)
    Uf = U.reshape(-1, d)
    _subtract_per_knot(sysk, sysk._local(j), Uf, Uf, V.reshape(-1, V.shape[2]), cols)


def _subtract_per_knot(sysk: kn.KnotSystem, knot, Ul, Ur, Yf, cols) -> None:
    """``Dk_j −= sym(U_lᵀ U_r)``, ``Bk_j −= U_lᵀ Y`` over each knot's epochs (three rows per
    epoch in ``Ul``, ``Ur`` (3E, d) and ``Yf`` (3E, p + 1); epochs in time order, so a knot's
    rows are contiguous): one BLAS product per knot."""
    starts = np.flatnonzero(np.r_[True, knot[1:] != knot[:-1]])
    ends = np.r_[starts[1:], knot.size]
    js = knot[starts]
    d = Ul.shape[1]
    DD = np.empty((starts.size, d, d))
    UB = np.empty((starts.size, d, Yf.shape[1]))
    for i in range(starts.size):
        a, b = 3 * starts[i], 3 * ends[i]
        if Ur is Ul:
            DD[i] = Ul[a:b].T @ Ul[a:b]  # symmetric (BLAS syrk)
        else:
            X = Ul[a:b].T @ Ur[a:b]
            DD[i] = 0.5 * (X + X.T)
        np.matmul(Ul[a:b].T, Yf[a:b], out=UB[i])
    ext = np.append(np.asarray(cols, np.int64), sysk.Bk.shape[2] - 1)
    at = (js[:, None, None], np.arange(d)[None, :, None], ext[None, None, :])
    if np.all(js[1:] > js[:-1]):
        sysk.Dk[js] -= DD
        sysk.Bk[at] -= UB
    else:
        np.subtract.at(sysk.Dk, js, DD)
        np.subtract.at(sysk.Bk, at, UB)
