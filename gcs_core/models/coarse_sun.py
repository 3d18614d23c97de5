"""Coarse two-axis digital Sun sensor (CSS), seed §4.2.3, Eq 4-16 to 4-20; ICD §5 ``coarse_sun``.

Observation model (the sensor looks along +x)::

    S_S = M C Ŝ_I                                                  (Eq 4-18)
    α = atan2(S_Sy, S_Sx),   β = atan2(S_Sz, S_Sx)                  (Eq 4-17)
    n_α = (α + b_α) / K_α,   n_β = (β + b_β) / K_β                   (Eq 4-16)

State (Eq 4-19): ``K_alpha, K_beta`` [rad/count] (data-book ``scale``) and ``b_alpha,
b_beta`` [rad] (data-book ``bias``); extended: ``align_1..3`` and ``time_offset``.

Partials (Eq 4-20a/b)::

    ∂n_i/∂K_i = −n_i / K_i,    ∂n_i/∂b_i = 1 / K_i
    ∂α/∂S_S = (−S_Sy, S_Sx, 0) / (S_Sx² + S_Sy²),   ∂β/∂S_S = (−S_Sz, 0, S_Sx) / (S_Sx² + S_Sz²)
    ∂S_S/∂δθ = M R [S_B ×]

A frame is valid when ``S_Sx > 0`` and both angles lie within ``fov_deg`` (half width)
plus a 10 % margin.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from gcs_core import units
from gcs_core.errors import InputError
from gcs_core.models import common
from gcs_core.models.base import Geometry, ObservationModel, ParamSpec, Prediction

#: (axis, tangent component of S_S, scale name, bias name)
AXES = (("alpha", 1, "K_alpha", "b_alpha"), ("beta", 2, "K_beta", "b_beta"))


class CoarseSunModel(ObservationModel):
    """Coarse digital Sun sensor, Eq 4-16/4-17: ``n = (atan2(S_S·, S_Sx) + b) / K`` per axis."""

    type_name = "coarse_sun"
    columns = ("n_alpha", "n_beta")
    components = ("n_alpha", "n_beta")
    unit = "counts"
    attitude_kind = "three_axis"
    book_keys = ("scale", "bias", "fov_deg")

    def parameters(self) -> tuple[ParamSpec, ...]:
        return common.cached_parameters(self, self._parameters)

    def _parameters(self) -> tuple[ParamSpec, ...]:
        scale = common.book_vector(self.sensor, "scale", 2)
        if np.any(scale == 0.0):
            raise InputError("'scale' [rad/count] must not be 0", key=common.book_key(self.sensor, "scale"))
        bias = common.book_vector(self.sensor, "bias", 2, default=(0.0, 0.0))
        specs = []
        for i, (axis, _, kname, _b) in enumerate(AXES):
            specs.append(
                ParamSpec(
                    kname,
                    "rad/count",
                    float(scale[i]),
                    0.05 * abs(scale[i]),
                    seed=True,
                    effect="scale",
                    description=f"{axis} scale factor (Eq 4-16)",
                )
            )
        for i, (axis, _, _k, bname) in enumerate(AXES):
            specs.append(
                ParamSpec(
                    bname,
                    "rad",
                    float(bias[i]),
                    1.0 * units.DEG,
                    seed=True,
                    effect="bias",
                    description=f"{axis} angle bias (Eq 4-16)",
                )
            )
        specs += common.alignment_specs(self.sensor, seed=False, sigma=0.02)
        specs.append(common.time_offset_spec())
        return tuple(specs)

    def sigma(self) -> np.ndarray:
        return np.full(2, common.noise_value(self.sensor))

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """Eq 4-16/4-17 at N frames: y (N, 2) [counts], d_att (N, 2, 3), d_par (N, 2)."""
        specs = self.parameters()
        p = common.merged_params(specs, params)
        if geom.sun_I is None:
            raise ValueError("coarse Sun sensor model needs sun_I in the geometry")
        n = geom.n
        M, dM = common.alignment_matrix(p)
        y = np.zeros((n, 2))
        J = np.zeros((n, 2, 3))  # ∂n/∂S_S
        d_par: dict[str, common.PartialSource] = {}
        with np.errstate(all="ignore"):
            bv = common.body_vector(geom, geom.sun_I, p["time_offset"])
            S = bv.v_B @ M.T
            for row, (_, comp, kname, bname) in enumerate(AXES):
                K, b = p[kname], p[bname]
                ang = np.arctan2(S[:, comp], S[:, 0])
                y[:, row] = (ang + b) / K
                for name, value in ((kname, -y[:, row] / K), (bname, np.full(n, 1.0 / K))):
                    col = np.zeros((n, 2))
                    col[:, row] = value
                    d_par[name] = col
                den = K * (S[:, 0] ** 2 + S[:, comp] ** 2)
                J[:, row, 0] = -S[:, comp] / den
                J[:, row, comp] = S[:, 0] / den
            d_att = bv.left((J.reshape(-1, 3) @ M).reshape(n, 2, 3))  # J M ∂S_B/∂δθ
            # formed when read (common.Partials): usually held
            for k, name in enumerate(common.ALIGN_NAMES):
                d_par[name] = lambda k=k: np.einsum("nij,nj->ni", J, bv.v_B @ dM[k].T)
            d_par["time_offset"] = lambda: np.einsum("nij,nj->ni", J, bv.d_dt @ M.T)
            valid = common.fov_square_ok(S, common.fov_rad(self.sensor))
        return common.finish(y, d_att, d_par, valid, specs)
