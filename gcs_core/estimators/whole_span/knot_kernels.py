"""Compiled loops of the knot corrections (:mod:`gcs_core.estimators.whole_span.knots`), with numba.

* :func:`_accumulate_fused` — per knot ``Σ uᵀu`` and ``Σ uᵀ [H | r]`` over a block's
  weighted rows, the knot rows ``u = w D C [I | Γ_j(t)]`` formed on the fly (one pass);
* :func:`_accumulate` — the same from rows already formed; :func:`_accumulate_numpy` its
  numpy form (segment sums), used without numba;
* :func:`correct_attitude` — ``exp(−[δθ×]) C`` with ``δθ = C α(t)`` (Rodrigues);
* :func:`rotate_by_rotvec` — ``exp(−[φ×]) C`` per frame (the read-out errors ε̂).

Engine selection is :data:`gcs_core.compiled.COMPILED`, as for the batch
kernels; without numba these stay plain Python and the numpy forms run.
"""

from __future__ import annotations

import numpy as np

from gcs_core.compiled import jit

_jit = jit()


@_jit
def _accumulate(U, H, rw, knot, cols, Dk, Bk):
    """``Dk[j] += Σ uᵀu``, ``Bk[j][:, cols] += Σ uᵀh``, ``Bk[j][:, -1] += Σ uᵀ r`` over the
    rows of each frame (U (N, m, d), H (N, m, k), rw (N, m), knot (N,), cols (k,))."""
    d = U.shape[2]
    last = Bk.shape[2] - 1
    for i in range(U.shape[0]):
        jj = knot[i]
        for r in range(U.shape[1]):
            for a in range(d):
                ua = U[i, r, a]
                if ua == 0.0:
                    continue
                for b in range(d):
                    Dk[jj, a, b] += ua * U[i, r, b]
                for q in range(cols.shape[0]):
                    Bk[jj, a, cols[q]] += ua * H[i, r, q]
                Bk[jj, a, last] += ua * rw[i, r]


def _accumulate_numpy(U, H, rw, knot, cols, Dk, Bk):
    """The numpy form of :func:`_accumulate` (frames are in time order: segment sums)."""
    if not U.shape[0]:
        return
    starts = np.flatnonzero(np.r_[True, knot[1:] != knot[:-1]])
    js = knot[starts]
    Dk[js] += np.add.reduceat(np.einsum("nra,nrb->nab", U, U), starts, axis=0)
    HB = np.add.reduceat(np.einsum("nra,nrq->naq", U, H), starts, axis=0)
    for q, c in enumerate(cols):
        Bk[js, :, c] += HB[:, :, q]
    Bk[js, :, -1] += np.add.reduceat(np.einsum("nra,nr->na", U, rw), starts, axis=0)


#: the largest finite double: :func:`numpy.nan_to_num`'s image of +inf
_MAX_FLOAT = float(np.finfo(np.float64).max)


@_jit
def _finite(v):
    """``numpy.nan_to_num`` of one value (NaN → 0, ±inf → ± the largest double)."""
    if v != v:
        return 0.0
    if v > _MAX_FLOAT:
        return _MAX_FLOAT
    if v < -_MAX_FLOAT:
        return -_MAX_FLOAT
    return v


@_jit
def _flush_knot(j, d, k, last, cols, accD, acc, Dk, Bk):
    """Add one knot's sums into ``Dk[j]``, ``Bk[j]`` (``accD`` holds its upper triangle:
    ``u_a u_b`` and ``u_b u_a`` are the same products, summed in the same order)."""
    for a in range(d):
        for b in range(d):
            Dk[j, a, b] += accD[a, b] if a <= b else accD[b, a]
        for q in range(k):
            Bk[j, a, cols[q]] += acc[a, q]
        Bk[j, a, last] += acc[a, k]


@_jit
def _add_row(u, d, k, Hr, row, accD, acc):
    """One knot row ``u`` into the knot's sums: ``accD += u uᵀ`` (upper triangle),
    ``acc += u Hr[row]``."""
    for a in range(d):
        ua = u[a]
        for b in range(a, d):
            accD[a, b] += ua * u[b]
        for q in range(k + 1):
            acc[a, q] += ua * Hr[row, q]


@_jit
def _accumulate_fused(D, C, w, t, knot, tau, R, Hr, m, cols, Dk, Bk):
    """:func:`knot_rows` and :func:`_accumulate` in one pass: the rows ``u`` are formed
    per frame and summed at once (D (N, m, 3), C (N, 3, 3), w (N, m); Hr (N·m, k + 1) the
    weighted static rows with the weighted residual last, C-ordered so that the loop
    along a row is unit-stride (a strided view of it ran 1.5× slower); the module
    docstring gives ``u``). Non-finite partials are read as :func:`numpy.nan_to_num`
    makes them (:func:`_finite`: no cleaned copy of D).

    The rows of a knot are summed two at a time, ``(acc + u₁h₁) + u₂h₂``: each sum
    meets its terms in row order, as one row at a time would (the same bits), with half
    the loads and stores of ``acc``."""
    d = Dk.shape[1]
    k = cols.shape[0]
    last = Bk.shape[2] - 1
    nR = R.shape[0]
    u = np.empty(6)  # the row held until its pair comes
    u2 = np.empty(6)
    acc = np.zeros((6, k + 1))
    accD = np.zeros((6, 6))
    cur = -1
    held = -1  # the held row's index in Hr, −1 for none
    for i in range(D.shape[0]):
        jj = knot[i]
        if jj != cur:
            if held >= 0:
                _add_row(u, d, k, Hr, held, accD, acc)
                held = -1
            if cur >= 0:
                _flush_knot(cur, d, k, last, cols, accD, acc, Dk, Bk)
            accD[:, :] = 0.0
            acc[:, :] = 0.0
            cur = jj
        s = -(t[i] - tau[jj])
        jr = jj if jj < nR else nR - 1
        for r in range(m):
            wr = w[i, r]
            if wr == 0.0:
                continue
            d0, d1, d2 = _finite(D[i, r, 0]) * wr, _finite(D[i, r, 1]) * wr, _finite(D[i, r, 2]) * wr
            v = u2 if held >= 0 else u
            for c in range(3):
                v[c] = d0 * C[i, 0, c] + d1 * C[i, 1, c] + d2 * C[i, 2, c]
            if d == 6:
                for c in range(3):
                    v[3 + c] = s * (v[0] * R[jr, 0, c] + v[1] * R[jr, 1, c] + v[2] * R[jr, 2, c])
            row = i * m + r
            if held < 0:
                held = row
                continue
            for a in range(d):
                ua, ub = u[a], u2[a]
                for b in range(a, d):
                    accD[a, b] = (accD[a, b] + ua * u[b]) + ub * u2[b]
                for q in range(k + 1):
                    acc[a, q] = (acc[a, q] + ua * Hr[held, q]) + ub * Hr[row, q]
            held = -1
    if held >= 0:
        _add_row(u, d, k, Hr, held, accD, acc)
    if cur >= 0:
        _flush_knot(cur, d, k, last, cols, accD, acc, Dk, Bk)


@_jit
def correct_attitude(C, t, knot, tau, z, R, out):
    """``out_i = exp(−[δθ×]) C_i`` with ``δθ = C_i α(t_i)`` (module docstring; Rodrigues)."""
    nR = R.shape[0]
    d = z.shape[1]
    a = np.empty(3)
    v = np.empty(3)
    for i in range(C.shape[0]):
        j = knot[i]
        jr = j if j < nR else nR - 1
        s = -(t[i] - tau[j])
        for c in range(3):
            a[c] = z[j, c]
        if d == 6 and nR > 0:
            for c in range(3):
                a[c] += s * (R[jr, c, 0] * z[j, 3] + R[jr, c, 1] * z[j, 4] + R[jr, c, 2] * z[j, 5])
        for c in range(3):
            v[c] = C[i, c, 0] * a[0] + C[i, c, 1] * a[1] + C[i, c, 2] * a[2]
        ang2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
        if ang2 < 1e-16:
            fa, fb = 1.0 - ang2 / 6.0, 0.5 - ang2 / 24.0
        else:
            ang = np.sqrt(ang2)
            fa, fb = np.sin(ang) / ang, (1.0 - np.cos(ang)) / ang2
        # exp(−[v×]) = I − fa [v×] + fb [v×]²
        K01, K02, K12 = -v[2], v[1], -v[0]
        E00 = 1.0 + fb * (-(v[1] * v[1] + v[2] * v[2]))
        E11 = 1.0 + fb * (-(v[0] * v[0] + v[2] * v[2]))
        E22 = 1.0 + fb * (-(v[0] * v[0] + v[1] * v[1]))
        E01 = -fa * K01 + fb * v[0] * v[1]
        E10 = fa * K01 + fb * v[0] * v[1]
        E02 = -fa * K02 + fb * v[0] * v[2]
        E20 = fa * K02 + fb * v[0] * v[2]
        E12 = -fa * K12 + fb * v[1] * v[2]
        E21 = fa * K12 + fb * v[1] * v[2]
        for c in range(3):
            c0, c1, c2 = C[i, 0, c], C[i, 1, c], C[i, 2, c]
            out[i, 0, c] = E00 * c0 + E01 * c1 + E02 * c2
            out[i, 1, c] = E10 * c0 + E11 * c1 + E12 * c2
            out[i, 2, c] = E20 * c0 + E21 * c1 + E22 * c2


@_jit
def rotate_by_rotvec(phi, C, out):
    """``out_i = exp(−[φ_i×]) C_i`` (:func:`gcs_core.frames.rotations.rotvec_to_dcm`, the same
    series below 1e-8 rad): the read-out errors' correction of the attitude."""
    for i in range(C.shape[0]):
        v0, v1, v2 = phi[i, 0], phi[i, 1], phi[i, 2]
        ang2 = v0 * v0 + v1 * v1 + v2 * v2
        ang = np.sqrt(ang2)
        if ang < 1e-8:
            fa, fb = 1.0 - ang2 / 6.0, 0.5 - ang2 / 24.0
        else:
            fa, fb = np.sin(ang) / ang, (1.0 - np.cos(ang)) / ang2
        # exp(−[v×]) = I − fa [v×] + fb [v×]²
        E00 = 1.0 - fb * (v1 * v1 + v2 * v2)
        E11 = 1.0 - fb * (v0 * v0 + v2 * v2)
        E22 = 1.0 - fb * (v0 * v0 + v1 * v1)
        E01 = fa * v2 + fb * v0 * v1
        E10 = -fa * v2 + fb * v0 * v1
        E02 = -fa * v1 + fb * v0 * v2
        E20 = fa * v1 + fb * v0 * v2
        E12 = fa * v0 + fb * v1 * v2
        E21 = -fa * v0 + fb * v1 * v2
        for c in range(3):
            c0, c1, c2 = C[i, 0, c], C[i, 1, c], C[i, 2, c]
            out[i, 0, c] = E00 * c0 + E01 * c1 + E02 * c2
            out[i, 1, c] = E10 * c0 + E11 * c1 + E12 * c2
            out[i, 2, c] = E20 * c0 + E21 * c1 + E22 * c2
