"""Fine two-axis digital Sun sensor (FSS), seed §4.2.4, Eq 4-22 to 4-26; ICD §5 ``fine_sun``.

Observation model (ICD reading). With ``S_S = M C Ŝ_I`` the unit Sun vector in sensor
axes (the sensor looks along +x)::

    tan α = S_Sy / S_Sx,   tan β = S_Sz / S_Sx
    tan α = A1 + A2 n_α + A3 sin(k_α tan α)                 (transfer function, Eq 4-23a)
    ⇒ n_α = (tan α − A1 − A3 sin(k_α tan α) − A4h sin(2 k_α tan α)) / A2
    n_β  = (tan β − B1 − B3 sin(k_β tan β) − B4h sin(2 k_β tan β)) / B2     (Eq 4-23b)

The seed state (Eq 4-26) holds the four physical parameters per axis, ``A1, A2, A3,
k_alpha`` and ``B1, B2, B3, k_beta`` (data-book ``coeff_alpha``, ``coeff_beta``). The
extended parameters are the alignment ``align_1..3``, a second harmonic of the transfer
function per axis ``A4h``, ``B4h`` (nominal 0, effect ``harmonic``) and ``time_offset``.

The eight coefficients of Eq 4-24 from the four of Eq 4-23
-----------------------------------------------------------
Eq 4-24 gives the angle from the counts, ``tan α = A1 + A2 n + A3 sin(A4 n + A5)
+ A6 sin(A7 n + A8)``. Write ``u = A1 + A2 n`` and substitute Eq 4-23 into itself once::

    tan α = u + A3 sin(k u + k A3 sin(k u)) ≈ u + A3 sin(k u) + k A3² sin(k u) cos(k u)
          = u + A3 sin(k A2 n + k A1) + (k A3²/2) sin(2 k A2 n + 2 k A1)

so ``A4 = k A2, A5 = k A1, A6 = k A3²/2, A7 = 2 k A2, A8 = 2 k A1`` (Eq 4-25), the same
for β with B and k_β: the eight are not free, and GCS estimates the four.
:func:`eight_coefficients` returns them; :func:`tan_from_counts` inverts Eq 4-23 exactly.

Partials (Eq 4-26a/b, α shown)::

    ∂n/∂A1 = −1/A2,  ∂n/∂A2 = −n/A2,  ∂n/∂A3 = −sin(k tan α)/A2,  ∂n/∂A4h = −sin(2k tan α)/A2
    ∂n/∂k  = −tan α (A3 cos(k tan α) + 2 A4h cos(2k tan α)) / A2
    ∂n/∂tan α = (1 − k A3 cos(k tan α) − 2 k A4h cos(2k tan α)) / A2
    ∂tan α/∂S_S = (−S_Sy/S_Sx², 1/S_Sx, 0),   ∂S_S/∂δθ = M R [S_B ×]

Second partials in the transfer-function parameters (``Prediction.d2_par``; t = tan α,
c_j = cos(j k t), s_j = sin(j k t)): the products ``A3 sin(k t)`` and ``1/A2`` make the
model bilinear, and with ``A3 ≈ 0`` the Gauss–Newton matrix alone leaves ``k`` flat while
the data still bend the cost along ``A3·k``::

    ∂²n/∂A1∂A2 = 1/A2²,   ∂²n/∂A2² = 2n/A2²,   ∂²n/∂A2∂A3 = s₁/A2²,   ∂²n/∂A2∂A4h = s₂/A2²
    ∂²n/∂A2∂k = t (A3 c₁ + 2 A4h c₂)/A2²,   ∂²n/∂A3∂k = −t c₁/A2,   ∂²n/∂A4h∂k = −2t c₂/A2
    ∂²n/∂k² = t² (A3 s₁ + 4 A4h s₂)/A2

A frame is valid when ``S_Sx > 0`` and both ``α`` and ``β`` lie within ``fov_deg`` (half
width) plus a 10 % margin.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from gcs_core.errors import InputError
from gcs_core.models import common
from gcs_core.models.base import Geometry, HeldPrediction, ObservationModel, ParamSpec, Prediction

#: (axis, data-book key, parameter names A1, A2, A3, k, harmonic, tangent component)
AXES = (
    ("alpha", "coeff_alpha", ("A1", "A2", "A3", "k_alpha"), "A4h", 1),
    ("beta", "coeff_beta", ("B1", "B2", "B3", "k_beta"), "B4h", 2),
)


def eight_coefficients(c1: float, c2: float, c3: float, k: float) -> tuple[float, ...]:
    """Eq 4-25: ``(A1..A8)`` of the series Eq 4-24 from the four parameters of Eq 4-23."""
    return (c1, c2, c3, k * c2, k * c1, k * c3**2 / 2.0, 2.0 * k * c2, 2.0 * k * c1)


def tan_from_counts(n, c1: float, c2: float, c3: float, k: float, *, harmonic: float = 0.0, iterations: int = 50):
    """Invert Eq 4-23: ``tan α`` with ``tan α = c1 + c2 n + c3 sin(k tan α) + h sin(2k tan α)``.

    Newton iteration started from the Eq 4-24 series (converges in a few steps for a
    sensor whose transfer function is monotonic, ``|k c3| + 2|k h| < 1``). Shape of ``n``.
    """
    n = np.asarray(n, dtype=float)
    u = c1 + c2 * n
    a = eight_coefficients(c1, c2, c3, k)
    x = u + a[2] * np.sin(a[3] * n + a[4]) + a[5] * np.sin(a[6] * n + a[7])  # Eq 4-24
    for _ in range(iterations):
        g = x - u - c3 * np.sin(k * x) - harmonic * np.sin(2.0 * k * x)
        dg = 1.0 - c3 * k * np.cos(k * x) - 2.0 * harmonic * k * np.cos(2.0 * k * x)
        step = g / dg
        x = x - step
        if np.all(np.abs(step) < 1e-15 * (1.0 + np.abs(x))):
            break
    return x


class FineSunModel(ObservationModel):
    """Fine digital Sun sensor, Eq 4-23: ``n = (tan α − A1 − A3 sin(k tan α)) / A2`` per axis."""

    type_name = "fine_sun"
    columns = ("n_alpha", "n_beta")
    components = ("n_alpha", "n_beta")
    unit = "counts"
    attitude_kind = "three_axis"
    book_keys = ("coeff_alpha", "coeff_beta", "fov_deg")
    seen_through = {"k_alpha": ("A3", "A4h"), "k_beta": ("B3", "B4h")}
    nonlinear_pairs = tuple(
        (a, b)
        for _, _, (c1, c2, c3, k), h, _ in AXES
        for a, b in ((c1, c2), (c2, c2), (c2, c3), (c3, k), (c2, k), (k, k), (c2, h), (h, k))
    )

    def parameters(self) -> tuple[ParamSpec, ...]:
        return common.cached_parameters(self, self._parameters)

    def _parameters(self) -> tuple[ParamSpec, ...]:
        specs = []
        for axis, key, names, _, _ in AXES:
            c = common.book_vector(self.sensor, key, 4)
            if c[1] == 0.0:
                raise InputError(
                    f"'{key}' second coefficient (counts-to-tangent slope) must not be 0",
                    key=common.book_key(self.sensor, key),
                )
            sig = (1e-3, 0.01 * abs(c[1]), 1e-3, max(0.1 * abs(c[3]), 1.0))
            units_ = ("1", "1/count", "1", "1")
            what = ("offset", "slope per count", "sine amplitude", "sine frequency")
            for i in range(4):
                specs.append(
                    ParamSpec(
                        names[i],
                        units_[i],
                        float(c[i]),
                        sig[i],
                        seed=True,
                        effect="transfer_function",
                        description=f"{axis} transfer function {what[i]} (Eq 4-23)",
                    )
                )
        specs += common.alignment_specs(self.sensor, seed=False, sigma=0.01)
        for axis, _, _, harm, _ in AXES:
            specs.append(
                ParamSpec(
                    harm,
                    "1",
                    0.0,
                    1e-3,
                    seed=False,
                    effect="harmonic",
                    description=f"{axis} transfer function second harmonic sin(2k tan)",
                )
            )
        specs.append(common.time_offset_spec())
        return tuple(specs)

    def sigma(self) -> np.ndarray:
        return np.full(2, common.noise_value(self.sensor))

    def held(self, geom: Geometry, params: Mapping[str, float], rows=None):
        """The transfer function (Eq 4-23) at the ``tan α, tan β`` of the held attitude,
        alignment and time offset (:meth:`ObservationModel.held`)."""
        p = common.merged_params(self.parameters(), params)
        if geom.sun_I is None:
            raise ValueError("fine Sun sensor model needs sun_I in the geometry")
        M, _ = common.alignment_matrix(p)
        with np.errstate(all="ignore"):
            S = common.body_vector(geom, geom.sun_I, p["time_offset"]).v_B @ M.T
            if rows is not None:
                S = S[rows]
            return _HeldTransfer((S[:, 1] / S[:, 0], S[:, 2] / S[:, 0]))

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """Eq 4-23 at N frames: y (N, 2) [counts], d_att (N, 2, 3), d_par (N, 2).

        The parameter partials are registered as functions (formed when read,
        :class:`~gcs_core.models.common.Partials`); with the harmonic at zero (held, the
        usual case) its ``sin(2k tan α)`` terms are zero and are not evaluated for ``y``.
        """
        specs = self.parameters()
        p = common.merged_params(specs, params)
        if geom.sun_I is None:
            raise ValueError("fine Sun sensor model needs sun_I in the geometry")
        n = geom.n
        M, dM = common.alignment_matrix(p)
        d_par: dict[str, common.PartialSource] = {}
        d2: dict[tuple[str, str], tuple[int, Any]] = {}  # (a, b) -> (component, ∂²y_c/∂a∂b)
        y = np.empty((n, 2))
        J = np.zeros((n, 2, 3))  # ∂n/∂S_S
        with np.errstate(all="ignore"):
            bv = common.body_vector(geom, geom.sun_I, p["time_offset"])
            S = bv.v_B @ M.T
            for row, (_, _, names, harm, comp) in enumerate(AXES):
                c1, c2, c3, k = (p[nm] for nm in names)
                h = p[harm]
                x = S[:, comp] / S[:, 0]  # tan α or tan β
                kx = k * x
                s1, co1 = np.sin(kx), np.cos(kx)
                if h != 0.0:
                    s2, co2 = np.sin(2.0 * kx), np.cos(2.0 * kx)
                    cnt = (x - c1 - c3 * s1 - h * s2) / c2
                    dn_dx = (1.0 - k * c3 * co1 - 2.0 * k * h * co2) / c2
                    dk = -x * (c3 * co1 + 2.0 * h * co2) / c2
                else:
                    cnt = (x - c1 - c3 * s1) / c2
                    dn_dx = (1.0 - k * c3 * co1) / c2
                    dk = -x * (c3 * co1) / c2
                y[:, row] = cnt
                d_par[names[0]] = lambda row=row, v=-1.0 / c2: common.column(n, 2, row, v)
                d_par[names[1]] = lambda row=row, v=cnt, c2=c2: common.column(n, 2, row, -v / c2)
                d_par[names[2]] = lambda row=row, v=s1, c2=c2: common.column(n, 2, row, -v / c2)
                d_par[names[3]] = lambda row=row, v=dk: common.column(n, 2, row, v)
                d_par[harm] = lambda row=row, kx=kx, c2=c2: common.column(n, 2, row, -np.sin(2.0 * kx) / c2)
                _second_partials(d2, n, row, names, harm, x, kx, cnt, c2, c3, h, s1, co1)
                J[:, row, 0] = -dn_dx * S[:, comp] / S[:, 0] ** 2
                J[:, row, comp] = dn_dx / S[:, 0]
            d_att = bv.left((J.reshape(-1, 3) @ M).reshape(n, 2, 3))  # J M ∂S_B/∂δθ
            for k_, name in enumerate(common.ALIGN_NAMES):
                d_par[name] = lambda k_=k_: np.einsum("nij,nj->ni", J, bv.v_B @ dM[k_].T)
            d_par["time_offset"] = lambda: np.einsum("nij,nj->ni", J, bv.d_dt @ M.T)
            valid = common.fov_square_ok(S, common.fov_rad(self.sensor))
        return common.finish(y, d_att, d_par, valid, specs, d2)


class _HeldTransfer:
    """Eq 4-23 at held ``tan α, tan β`` (N,) each: the transfer function alone, in its
    parameters (:meth:`FineSunModel.held`)."""

    def __init__(self, tans):
        self.tans = tans

    def __call__(self, params: Mapping[str, float], wanted=None) -> HeldPrediction:
        n = self.tans[0].size
        y = np.empty((n, 2))
        d_par: dict = {}
        d2: dict = {}
        for row, (_, _, names, harm, _) in enumerate(AXES):
            a1, a2, a3, k_ = names
            c1, c2, c3, k = (float(params[nm]) for nm in names)
            h = float(params.get(harm, 0.0))
            x = self.tans[row]
            kx = k * x
            s1, co1 = np.sin(kx), np.cos(kx)
            xc = x * co1
            if h != 0.0:
                s2 = np.sin(2.0 * kx)
                cnt = (x - c1 - c3 * s1 - h * s2) / c2
                dk = -(c3 * xc + 2.0 * h * x * np.cos(2.0 * kx)) / c2
            else:
                cnt = (x - c1 - c3 * s1) / c2
                dk = -(c3 / c2) * xc
            y[:, row] = cnt
            d_par.update({a1: (row, -1.0 / c2), a2: (row, -cnt / c2), a3: (row, -s1 / c2), k_: (row, dk)})
            if harm in params and (wanted is None or harm in wanted):
                d_par[harm] = (row, -np.sin(2.0 * kx) / c2)
            _second_partials(d2, n, row, names, harm, x, kx, cnt, c2, c3, h, s1, co1)
        return HeldPrediction(y, d_par, d2)


def _second_partials(
    d2: dict, n: int, row: int, names, harm: str, x, kx, cnt, c2: float, c3: float, h: float, s1, co1
) -> None:
    """Register the second partials of one axis (module docstring, ``Prediction.d2_par``)
    as ``(row, function)`` entries formed when read: ``x`` = tan, ``kx`` = k tan, ``cnt``
    = n, ``s1``, ``co1`` = sin, cos of ``kx`` (N,)."""
    a1, a2, a3, k = names
    inv, inv2 = 1.0 / c2, 1.0 / c2**2
    d2[(a1, a2)] = (row, inv2)
    d2[(a2, a2)] = (row, lambda: (2.0 * inv2) * cnt)
    d2[(a2, a3)] = (row, lambda: inv2 * s1)
    d2[(a3, k)] = (row, lambda: -inv * (x * co1))
    if h == 0.0:
        d2[(a2, k)] = (row, lambda: (c3 * inv2) * (x * co1))
        d2[(k, k)] = (row, lambda: (c3 * inv) * (x * x * s1))
    else:
        d2[(a2, k)] = (row, lambda: inv2 * x * (c3 * co1 + 2.0 * h * np.cos(2.0 * kx)))
        d2[(k, k)] = (row, lambda: inv * x * x * (c3 * s1 + 4.0 * h * np.sin(2.0 * kx)))
    d2[(a2, harm)] = (row, lambda: inv2 * np.sin(2.0 * kx))
    d2[(harm, k)] = (row, lambda: (-2.0 * inv) * x * np.cos(2.0 * kx))
