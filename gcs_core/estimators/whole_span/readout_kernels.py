"""Compiled loops of the read-out noise elimination (:mod:`gcs_core.estimators.whole_span.readout`),
with numba (:data:`gcs_core.compiled.COMPILED`; without numba the numpy forms in that module run):

* :func:`_frame_products_into` — per frame ``F = Σ D̃ᵀD̃``, ``D̃ᵀ[H̃ | r̃]`` and ``F C``, added
  into its epoch (one epoch per frame: the per-frame products);
* :func:`_scatter` — per-frame products added to the window's epochs;
* :func:`_row_readout` — per row the read-out variance ``σ_e² |D|²`` and ``D ε̂``;
* :func:`_epoch_solve` — per epoch the Cholesky factor of ``M = F + σ_e⁻² I`` and the
  factored rows ``L⁻¹ G``, ``L⁻¹ F C`` and the read-out error's step;
* :func:`_epoch_knot_rows` — the epochs' knot rows ``W [I | Γ_j(t)]``;
* :func:`_epoch_step` — the read-out errors' part of a joint step, per epoch.
"""

from __future__ import annotations

import numpy as np

from gcs_core.compiled import jit

_jit = jit()


@_jit
def _cholesky3(F, e, inv_e2):
    """The Cholesky factor ``L`` of epoch ``e``'s ``M = F_e + σ_e⁻² I`` (3 × 3, positive
    definite) as ``(1/l00, l10, l20, 1/l11, l21, 1/l22)``: the diagonal's reciprocals, three
    divisions per epoch."""
    i00 = 1.0 / np.sqrt(F[e, 0, 0] + inv_e2)
    l10, l20 = F[e, 0, 1] * i00, F[e, 0, 2] * i00
    l11 = np.sqrt(F[e, 1, 1] + inv_e2 - l10 * l10)
    i11 = 1.0 / l11
    l21 = (F[e, 1, 2] - l20 * l10) * i11
    i22 = 1.0 / np.sqrt(F[e, 2, 2] + inv_e2 - l20 * l20 - l21 * l21)
    return i00, l10, l20, i11, l21, i22


@_jit
def _epoch_solve(F, G, FC, inv_e2, V, W, y_eps):
    """Per epoch the Cholesky factor ``L`` of ``M = F + σ_e⁻² I`` (:func:`_cholesky3`),
    ``V = L⁻¹ G``, ``W = L⁻¹ FC`` (when FC has the epochs) and
    ``y_eps = M⁻¹ g_ε = L⁻ᵀ V[:, last]`` (the read-out error's step)."""
    last = G.shape[2] - 1
    for e in range(F.shape[0]):
        i00, l10, l20, i11, l21, i22 = _cholesky3(F, e, inv_e2)
        for q in range(G.shape[2]):
            v0 = G[e, 0, q] * i00
            v1 = (G[e, 1, q] - l10 * v0) * i11
            V[e, 0, q] = v0
            V[e, 1, q] = v1
            V[e, 2, q] = (G[e, 2, q] - l20 * v0 - l21 * v1) * i22
        if FC.shape[0]:
            for q in range(3):
                v0 = FC[e, 0, q] * i00
                v1 = (FC[e, 1, q] - l10 * v0) * i11
                W[e, 0, q] = v0
                W[e, 1, q] = v1
                W[e, 2, q] = (FC[e, 2, q] - l20 * v0 - l21 * v1) * i22
        y2 = V[e, 2, last] * i22
        y1 = (V[e, 1, last] - l21 * y2) * i11
        y_eps[e, 2] = y2
        y_eps[e, 1] = y1
        y_eps[e, 0] = (V[e, 0, last] - l10 * y1 - l20 * y2) * i00


@_jit
def _epoch_knot_rows(W, t, j, tau, R, U):
    """``U = W [I | Γ_j(t)]`` per epoch (E, 3, d), with ``Γ_j(t) = −(t − τ_j) R_j`` (d = 6;
    R zero when the grid has no interval)."""
    d = U.shape[2]
    nR = R.shape[0]
    for e in range(W.shape[0]):
        jj = j[e]
        jr = jj if jj < nR else nR - 1
        s = -(t[e] - tau[jj])
        for r in range(3):
            for c in range(3):
                U[e, r, c] = W[e, r, c]
            if d == 6:
                w0, w1, w2 = W[e, r, 0], W[e, r, 1], W[e, r, 2]
                for c in range(3):
                    U[e, r, 3 + c] = s * (w0 * R[jr, 0, c] + w1 * R[jr, 1, c] + w2 * R[jr, 2, c])


@_jit
def _scatter(idx, ext, X, G, Fb, F, FCb, FC):
    """``G[idx[i], :, ext[q]] += X[i, :, q]``, ``F[idx[i]] += Fb[i]`` and, when ``FCb`` has
    the frames, ``FC[idx[i]] += FCb[i]`` (repeated epochs add)."""
    with_fc = FCb.shape[0] > 0
    nq = ext.shape[0]
    for i in range(idx.shape[0]):
        e = idx[i]
        for r in range(3):
            for c in range(3):
                F[e, r, c] += Fb[i, r, c]
                if with_fc:
                    FC[e, r, c] += FCb[i, r, c]
            for q in range(nq):  # along X's rows (contiguous)
                G[e, r, ext[q]] += X[i, r, q]


@_jit
def _frame_products_into(D, w, Hr, C, idx, ext, F, G, FC):
    """Frame ``i``'s products added into epoch ``e = idx[i]``, with ``D̃_r = w_r D_r`` (rows of
    weight 0 skipped, NaN partials as 0): ``F[e] += Σ_r D̃_rᵀ D̃_r``, ``G[e, :, ext[q]] += Σ_r
    D̃_rᵀ [h̃_r | r̃_r][q]`` (the last of ``ext`` the residual column) and, when ``FC`` has
    epochs, ``FC[e] += F_i C_i`` (D (n, m, 3), w (n, m), Hr (n·m, k + 1) the weighted
    static rows with the weighted residual last, C-ordered; C (n, 3, 3))."""
    n, m = D.shape[0], D.shape[1]
    k1 = Hr.shape[1]
    with_fc = FC.shape[0] > 0
    d = np.empty(3)
    Fi = np.empty((3, 3))
    for i in range(n):
        e = idx[i]
        Fi[:, :] = 0.0
        for r in range(m):
            wr = w[i, r]
            if wr == 0.0:
                continue
            for a in range(3):
                v = D[i, r, a] * wr
                d[a] = v if v == v else 0.0  # NaN partials count as 0 (np.nan_to_num)
            row = i * m + r
            for a in range(3):
                da = d[a]
                for b in range(3):
                    Fi[a, b] += da * d[b]
                for q in range(k1):
                    G[e, a, ext[q]] += da * Hr[row, q]
        for a in range(3):
            for b in range(3):
                F[e, a, b] += Fi[a, b]
        if with_fc:
            for a in range(3):
                for c in range(3):
                    FC[e, a, c] += Fi[a, 0] * C[i, 0, c] + Fi[a, 1] * C[i, 1, c] + Fi[a, 2] * C[i, 2, c]


@_jit
def _epoch_step(F, FC, Gdx, a, base, inv_e2, out):
    """Per epoch ``out = base − M⁻¹ (G_x dx + F C a)``, ``M = F + σ_e⁻² I`` (:func:`_cholesky3`; F, FC
    (E, 3, 3), Gdx and a (E, 3) the statics' and the knots' parts, base (E, 3))."""
    for e in range(F.shape[0]):
        r0 = Gdx[e, 0] + FC[e, 0, 0] * a[e, 0] + FC[e, 0, 1] * a[e, 1] + FC[e, 0, 2] * a[e, 2]
        r1 = Gdx[e, 1] + FC[e, 1, 0] * a[e, 0] + FC[e, 1, 1] * a[e, 1] + FC[e, 1, 2] * a[e, 2]
        r2 = Gdx[e, 2] + FC[e, 2, 0] * a[e, 0] + FC[e, 2, 1] * a[e, 1] + FC[e, 2, 2] * a[e, 2]
        i00, l10, l20, i11, l21, i22 = _cholesky3(F, e, inv_e2)
        v0 = r0 * i00
        v1 = (r1 - l10 * v0) * i11
        y2 = (r2 - l20 * v0 - l21 * v1) * i22 * i22
        y1 = (v1 - l21 * y2) * i11
        y0 = (v0 - l10 * y1 - l20 * y2) * i00
        out[e, 0] = base[e, 0] - y0
        out[e, 1] = base[e, 1] - y1
        out[e, 2] = base[e, 2] - y2


@_jit
def _row_readout(D, eps, sig_e2, var, De):
    """Per row ``var = σ_e² |D|²`` and ``De = D · ε̂`` of its frame (D (n, m, 3), NaN
    partials as 0; eps (n, 3), or (0, 3) for none: De is left as it is)."""
    with_eps = eps.shape[0] > 0
    for i in range(D.shape[0]):
        for r in range(D.shape[1]):
            s, de = 0.0, 0.0
            for a in range(3):
                v = D[i, r, a]
                if v == v:
                    s += v * v
                    if with_eps:
                        de += v * eps[i, a]
            var[i, r] = sig_e2 * s
            if with_eps:
                De[i, r] = de
