"""Compiled inner loops of the batch linearization (seed §3.2.1, §4.1), with numba.

Loops over gyro knots or sensor frames, each a few dozen flops per element, that
numpy can only express as chains of small batched products with (N, 3, 18)
temporaries; compiled, each is one pass over its data.

* :func:`rates` — the corrected body rates ``ω = Mᵀ (G⁻¹ y − b − ḃ τ)`` (Eq 4-32
  inverted) with the intermediate ``G⁻¹ y`` and ``u = G⁻¹ y − b(t)``;
* :func:`propagate` — the attitude along the gyro knots (Eq 4-38, Eq 4-10, Eq 4-8)::

      Q_k = q(ω_k Δ_k) ⊗ Q_{k−1},   q(φ) = (φ̂ sin(|φ|/2), cos(|φ|/2)),   C_k = C(Q_k)

  sequentially, each product renormalized (the numpy path composes the same steps by a
  blocked scan; composition is associative, so only the round-off differs).
* :func:`gyro_sums` — the cumulative sums ``E_k = E_{k0} + Σ_{j≤k} C_jᵀ ∂ω_j/∂p Δ_j``
  of the gyro-carried attitude (module docstring of :mod:`gcs_core.problem.attitude`),
  the increments formed from the structure of ``∂ω/∂p`` (Eq 4-32 inverted)::

      C_jᵀ ∂ω/∂G_ac = −(C_jᵀ Mᵀ G⁻¹)_{:,a} (G⁻¹ y)_c,   C_jᵀ ∂ω/∂b = −C_jᵀ Mᵀ,
      C_jᵀ ∂ω/∂a_k = C_jᵀ (∂M/∂a_k)ᵀ u,               C_jᵀ ∂ω/∂ḃ = −C_jᵀ Mᵀ τ_j

* :func:`chain_rows` — whole rows of one sensor block: the attitude columns
  ``w D C [M_a | X]`` (``D`` the model's ∂y/∂δθ, ``C`` the frame attitude, ``X = E_j``)
  and the model's own (weighted) parameter columns, written row by row into the
  block's H, so that each row is written once (column-by-column writes into an (n, m, k)
  array touch every cache line k times); a row weighted zero is written as exact zeros.
* :func:`chain_gram` — the same rows, never stored: formed a tile at a time in a small
  buffer that stays in cache and folded into ``Σ rowᵀ row`` by BLAS ``dsyrk`` (scipy's
  ``cython_blas``, called through a ctypes pointer given as an argument so that the
  compiled code can be cached). The normal equations need only that sum; writing and
  re-reading the whole (N·m, k) H was a third of a linearization.

Engine selection is :data:`gcs_core.compiled.COMPILED` (numba importable and
``GCS_NO_NUMBA`` unset); without it the callers use their numpy forms (the same numbers
to round-off) and these functions stay plain Python, unused. The kernels are compiled on
first use and cached on disk (``__pycache__``), like the Kalman kernel.
"""

from __future__ import annotations

import ctypes
import math

import numpy as np

from gcs_core.compiled import COMPILED, jit

__all__ = ["DSYRK", "rates", "propagate", "gyro_sums", "chain_rows", "chain_gram"]

#: ``@numba.njit(cache=True, fastmath=False)``, or the identity without numba.
_jit = jit(fastmath=False)
_jit_fast = jit(fastmath={"contract", "arcp", "nsz"})


def _blas_syrk():
    """BLAS ``dsyrk`` (Fortran calling convention: every argument by pointer) as a ctypes
    function, or None where scipy's ``cython_blas`` cannot be reached."""
    try:
        from numba.extending import get_cython_function_address

        addr = get_cython_function_address("scipy.linalg.cython_blas", "dsyrk")
    except Exception:  # noqa: BLE001 — any failure: the unfused path
        return None
    return ctypes.CFUNCTYPE(None, *([ctypes.c_void_p] * 10))(addr)


#: ``dsyrk`` for :func:`chain_gram` (None: use :func:`chain_rows` and numpy's product)
DSYRK = _blas_syrk() if COMPILED else None
#: rows per tile of :func:`chain_gram` (a tile of 27 columns is 28 KB: it stays in L1/L2)
GRAM_TILE_ROWS = 128


@_jit
def rates(y, Ginv, b, bdot, M, tau, Gy, u, omega):
    """Eq 4-32 inverted, row by row, into ``Gy``, ``u``, ``omega`` (n, 3)::

    G⁻¹ y,   u = G⁻¹ y − b − ḃ τ,   ω = Mᵀ u
    """
    for k in range(y.shape[0]):
        for c in range(3):
            g = Ginv[c, 0] * y[k, 0] + Ginv[c, 1] * y[k, 1] + Ginv[c, 2] * y[k, 2]
            Gy[k, c] = g
            u[k, c] = g - b[c] - tau[k] * bdot[c]
        for a in range(3):
            omega[k, a] = u[k, 0] * M[0, a] + u[k, 1] * M[1, a] + u[k, 2] * M[2, a]


@_jit
def propagate(q_s, omega, dt, Q, C):
    """Knot attitudes from the checkpoint ``q_s`` (4,): ``Q`` (n, 4) and ``C`` (n, 3, 3).

    ``Q_k = q(ω_k Δ_k) ⊗ Q_{k−1}`` with ``Q_{−1} = q_s`` (module docstring); the step
    quaternion of Eq 4-38 uses the series ``sin(x/2)/x ≈ 1/2 − x²/48`` below 1e-12 rad.
    """
    p1, p2, p3, p4 = q_s[0], q_s[1], q_s[2], q_s[3]
    for k in range(omega.shape[0]):
        f1, f2, f3 = omega[k, 0] * dt[k], omega[k, 1] * dt[k], omega[k, 2] * dt[k]
        ang = math.sqrt(f1 * f1 + f2 * f2 + f3 * f3)
        half = 0.5 * ang
        s = 0.5 - ang * ang / 48.0 if ang < 1e-12 else math.sin(half) / ang
        a1, a2, a3, a4 = f1 * s, f2 * s, f3 * s, math.cos(half)
        # Eq 4-10b: C(q'') = C(a) C(p)
        b1 = a4 * p1 + a3 * p2 - a2 * p3 + a1 * p4
        b2 = -a3 * p1 + a4 * p2 + a1 * p3 + a2 * p4
        b3 = a2 * p1 - a1 * p2 + a4 * p3 + a3 * p4
        b4 = -a1 * p1 - a2 * p2 - a3 * p3 + a4 * p4
        nrm = 1.0 / math.sqrt(b1 * b1 + b2 * b2 + b3 * b3 + b4 * b4)
        p1, p2, p3, p4 = b1 * nrm, b2 * nrm, b3 * nrm, b4 * nrm
        Q[k, 0], Q[k, 1], Q[k, 2], Q[k, 3] = p1, p2, p3, p4
        # Eq 4-8: C = (q4² − |e|²) I + 2 e eᵀ − 2 q4 [e×]
        sq = p4 * p4 - (p1 * p1 + p2 * p2 + p3 * p3)
        c1, c2, c3 = 2.0 * p4 * p1, 2.0 * p4 * p2, 2.0 * p4 * p3
        e12, e13, e23 = 2.0 * (p1 * p2), 2.0 * (p1 * p3), 2.0 * (p2 * p3)
        C[k, 0, 0] = sq + 2.0 * (p1 * p1)
        C[k, 1, 1] = sq + 2.0 * (p2 * p2)
        C[k, 2, 2] = sq + 2.0 * (p3 * p3)
        C[k, 0, 1] = e12 + c3
        C[k, 1, 0] = e12 - c3
        C[k, 0, 2] = e13 - c2
        C[k, 2, 0] = e13 + c2
        C[k, 1, 2] = e23 + c1
        C[k, 2, 1] = e23 - c1


@_jit_fast
def gyro_sums(C, MtGinv, M, dM, Gy, u, tau, dt, E_s, E):
    """``E[0] = E_s``, ``E[j+1] = E[j] + C_jᵀ ∂ω_j/∂p Δ_j`` (module docstring), in place.

    C : (n+1, 3, 3) block attitudes (``C[j+1]`` is knot j of the rows); MtGinv, M : (3, 3);
    dM : (3, 3, 3) ``∂M/∂a_k``; Gy, u : (n, 3) ``G⁻¹ y`` and ``G⁻¹ y − b(t)``; tau, dt : (n,);
    E_s : (3, 18) the checkpoint; E : (n+1, 3, 18) output. Columns follow
    ``GyroAttitude.param_names``: G_ac at 3a + c, bias 9..11, align 12..14, bias rate 15..17.
    """
    s = np.empty(54)  # the running sum, E_j flattened
    s[:] = E_s.ravel()
    E[0] = E_s
    Ef = E.reshape(E.shape[0], 54)
    z = np.empty((3, 3))
    for j in range(u.shape[0]):
        Cj = C[j + 1]
        d = dt[j]
        g0, g1, g2 = Gy[j, 0] * d, Gy[j, 1] * d, Gy[j, 2] * d
        for k in range(3):  # z[k] = (∂M/∂a_k)ᵀ u
            for l in range(3):
                z[k, l] = dM[k, 0, l] * u[j, 0] + dM[k, 1, l] * u[j, 1] + dM[k, 2, l] * u[j, 2]
        for b in range(3):  # row b of C_jᵀ ∂ω/∂p Δ_j
            c0, c1, c2 = Cj[0, b], Cj[1, b], Cj[2, b]
            base = 18 * b
            for a in range(3):
                V = c0 * MtGinv[0, a] + c1 * MtGinv[1, a] + c2 * MtGinv[2, a]  # (Cᵀ Mᵀ G⁻¹)_ba
                N = c0 * M[a, 0] + c1 * M[a, 1] + c2 * M[a, 2]  # (Cᵀ Mᵀ)_ba
                s[base + 3 * a] -= V * g0
                s[base + 3 * a + 1] -= V * g1
                s[base + 3 * a + 2] -= V * g2
                nb = -N * d
                s[base + 9 + a] += nb
                s[base + 15 + a] += nb * tau[j]
                s[base + 12 + a] += (c0 * z[a, 0] + c1 * z[a, 1] + c2 * z[a, 2]) * d
        row = Ef[j + 1]
        for q in range(54):
            row[q] = s[q]


@_jit_fast
def chain_rows(D, w, C, E, jidx, Ma, rsel, psel, P, pcol, out):
    """One block's rows: ``w_ir D_ir C_i [M_a[:, rsel] | E[jidx_i][:, psel]]`` in columns
    ``0 .. len(rsel) + len(psel) − 1`` of ``out``, then the prepared columns ``P`` (module
    docstring).

    D : (n, m, 3); w : (n, m) row weights; C : (n, 3, 3); E : (L, 3, 18); jidx : (n,) rows
    of E; Ma : (3, 3); rsel, psel : column positions; P : (q, n, m) further columns,
    already weighted, written to ``out[..., pcol[q]]`` (added when that is an attitude
    column); out : (n, m, K). A row of zero weight is written as K exact zeros (an unused
    frame whose partials are NaN must not reach ``Hᵀ H``).
    """
    nr = rsel.shape[0]
    npp = psel.shape[0]
    ka = nr + npp
    # T = [M_a[:, rsel] | E_j[:, psel]] (3, ka), the factor after C in ∂δθ/∂x, as
    # three contiguous rows, gathered once per frame (the m rows of a frame share it) so
    # that the inner loop over columns is unit-stride
    T0, T1, T2 = np.empty(ka), np.empty(ka), np.empty(ka)
    for o in range(nr):
        a = rsel[o]
        T0[o], T1[o], T2[o] = Ma[0, a], Ma[1, a], Ma[2, a]
    for i in range(D.shape[0]):
        Ej = E[jidx[i]]
        for o in range(npp):
            p = psel[o]
            T0[nr + o], T1[nr + o], T2[nr + o] = Ej[0, p], Ej[1, p], Ej[2, p]
        for r in range(D.shape[1]):
            wr = w[i, r]
            row = out[i, r]
            if wr == 0.0:
                row[:] = 0.0
                continue
            d0, d1, d2 = D[i, r, 0] * wr, D[i, r, 1] * wr, D[i, r, 2] * wr
            x0 = d0 * C[i, 0, 0] + d1 * C[i, 1, 0] + d2 * C[i, 2, 0]  # x = w D C
            x1 = d0 * C[i, 0, 1] + d1 * C[i, 1, 1] + d2 * C[i, 2, 1]
            x2 = d0 * C[i, 0, 2] + d1 * C[i, 1, 2] + d2 * C[i, 2, 2]
            for o in range(ka):
                row[o] = x0 * T0[o] + x1 * T1[o] + x2 * T2[o]
            for q in range(P.shape[0]):
                c = pcol[q]
                if c < ka:
                    row[c] += P[q, i, r]
                else:
                    row[c] = P[q, i, r]


@_jit_fast
def chain_gram(D, w, C, E, jidx, Ma, rsel, psel, P, pcol, gidx, Wg, sg, G, buf, syrk):
    """``G += Σ rowᵀ row`` over the rows :func:`chain_rows` would write (same arguments
    but ``out``), with the term of frames between gyro knots included: frame i with
    ``gidx[i] = g ≥ 0`` adds ``sg[g] (w D)_i Wg[g]`` in the gyro columns (what
    :meth:`~gcs_core.problem.attitude.FrameAttitude.fill_rows` adds after :func:`chain_rows`).
    Each row is formed in the tile ``buf`` (T, K) and every T rows (or fewer at the end)
    the tile is folded in by ``syrk`` (BLAS dsyrk, uplo "U", trans "N" on the Fortran view
    ``bufᵀ``). ``G`` (K, K) C-ordered receives the Fortran upper triangle, i.e. its own
    lower triangle (the caller mirrors it). K = G.shape[0].
    """
    K = G.shape[0]
    T = buf.shape[0]
    m = D.shape[1]
    nr = rsel.shape[0]
    npp = psel.shape[0]
    ka = nr + npp
    uplo = np.array([85], np.uint8)  # "U"
    trans = np.array([78], np.uint8)  # "N"
    kk = np.array([K], np.int32)
    nn = np.array([0], np.int32)
    one = np.array([1.0])
    T0, T1, T2 = np.empty(ka), np.empty(ka), np.empty(ka)
    for o in range(nr):
        a = rsel[o]
        T0[o], T1[o], T2[o] = Ma[0, a], Ma[1, a], Ma[2, a]
    cnt = 0
    for i in range(D.shape[0]):
        Ej = E[jidx[i]]
        for o in range(npp):
            p = psel[o]
            T0[nr + o], T1[nr + o], T2[nr + o] = Ej[0, p], Ej[1, p], Ej[2, p]
        for r in range(m):
            wr = w[i, r]
            if wr == 0.0:
                continue  # a zero row adds nothing
            row = buf[cnt]
            d0, d1, d2 = D[i, r, 0] * wr, D[i, r, 1] * wr, D[i, r, 2] * wr
            x0 = d0 * C[i, 0, 0] + d1 * C[i, 1, 0] + d2 * C[i, 2, 0]
            x1 = d0 * C[i, 0, 1] + d1 * C[i, 1, 1] + d2 * C[i, 2, 1]
            x2 = d0 * C[i, 0, 2] + d1 * C[i, 1, 2] + d2 * C[i, 2, 2]
            for o in range(ka):
                row[o] = x0 * T0[o] + x1 * T1[o] + x2 * T2[o]
            g = gidx[i]
            if g >= 0:
                sgg = sg[g]
                for o in range(npp):
                    p = psel[o]
                    row[nr + o] += sgg * (d0 * Wg[g, 0, p] + d1 * Wg[g, 1, p] + d2 * Wg[g, 2, p])
            for o in range(ka, K):
                row[o] = 0.0
            for q in range(P.shape[0]):
                c = pcol[q]
                row[c] += P[q, i, r]
            cnt += 1
        if cnt + m > T or (i == D.shape[0] - 1 and cnt > 0):
            nn[0] = cnt
            syrk(
                uplo.ctypes,
                trans.ctypes,
                kk.ctypes,
                nn.ctypes,
                one.ctypes,
                buf.ctypes,
                kk.ctypes,
                one.ctypes,
                G.ctypes,
                kk.ctypes,
            )
            cnt = 0
