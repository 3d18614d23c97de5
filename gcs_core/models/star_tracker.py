"""Fixed-head star tracker (FHST), seed §4.2.6, Eq 4-29 to 4-31; ICD §5 ``star_tracker``.

Observation model (ICD reading of Eq 4-29/4-30; the tracker looks along sensor +x)::

    F_S = M C F_I                                    (Eq 4-30, M = T3(a3) T2(a2) T1(a1))
    h = asin(F_Sz) / S_H,   v = atan2(F_Sy, F_Sx) / S_V                    (Eq 4-29)

State (Eq 4-31): the alignment angles ``align_1..3`` (``a1`` is the rotation about the
boresight x) and the scale factors ``scale_h``, ``scale_v``; extended: ``time_offset``
(``F_B(t + Δt) = R(Δt) C F_I``, stars being fixed in GCI; :mod:`gcs_core.models.common`).

Partials (after Eq 4-31)::

    ∂h/∂F_S = (0, 0, 1) / (S_H sqrt(1 − F_Sz²))
    ∂v/∂F_S = (−F_Sy, F_Sx, 0) / (S_V (F_Sx² + F_Sy²))
    ∂F_S/∂δθ = M R [F_B ×],   ∂F_S/∂a_k = ∂M/∂a_k F_B,   ∂F_S/∂Δt = −M (ω_B × F_B)
    ∂h/∂S_H = −h / S_H,   ∂v/∂S_V = −v / S_V

``geom.star_I`` holds the catalog unit vector of each frame's identified star (from the
``ra, dec`` telemetry columns). A frame is valid when the star lies in front of the
tracker and both angles are within ``fov_deg`` (half width) plus a 10 % margin.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from gcs_core.io.types import Table
from gcs_core.models import common
from gcs_core.models.base import Geometry, ObservationModel, ParamSpec, Prediction


class StarTrackerModel(ObservationModel):
    """Fixed-head star tracker, Eq 4-29/4-30: ``h = asin(F_Sz)/S_H``, ``v = atan2(F_Sy, F_Sx)/S_V``."""

    type_name = "star_tracker"
    columns = ("h", "v", "ra", "dec")
    components = ("h", "v")
    unit = "rad"
    attitude_kind = "three_axis"
    book_keys = ("scale", "fov_deg")

    def parameters(self) -> tuple[ParamSpec, ...]:
        return common.cached_parameters(self, self._parameters)

    def _parameters(self) -> tuple[ParamSpec, ...]:
        scale = common.book_vector(self.sensor, "scale", 2, default=(1.0, 1.0))
        specs = list(common.alignment_specs(self.sensor, seed=True, sigma=0.01))
        specs += [
            ParamSpec(
                "scale_h",
                "1",
                float(scale[0]),
                1e-3,
                seed=True,
                effect="scale",
                description="scale factor S_H of the h axis (Eq 4-29a)",
            ),
            ParamSpec(
                "scale_v",
                "1",
                float(scale[1]),
                1e-3,
                seed=True,
                effect="scale",
                description="scale factor S_V of the v axis (Eq 4-29b)",
            ),
            common.time_offset_spec(),
        ]
        return tuple(specs)

    def sigma(self) -> np.ndarray:
        return np.full(2, common.noise_value(self.sensor))

    def measurements(self, table: Table) -> tuple[np.ndarray, np.ndarray]:
        return table.t, table.stack(("h", "v"))

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """Eq 4-29/4-30 at N frames: y (N, 2) [rad], d_att (N, 2, 3), d_par (N, 2)."""
        specs = self.parameters()
        p = common.merged_params(specs, params)
        if geom.star_I is None:
            raise ValueError("star tracker model needs star_I in the geometry")
        M, dM = common.alignment_matrix(p)
        S_H, S_V = p["scale_h"], p["scale_v"]
        with np.errstate(all="ignore"):
            bv = common.body_vector(geom, geom.star_I, p["time_offset"])
            F = bv.v_B @ M.T  # F_S (N, 3)
            asin_z = np.arcsin(np.clip(F[:, 2], -1.0, 1.0))
            atan_yx = np.arctan2(F[:, 1], F[:, 0])
            y = np.column_stack([asin_z / S_H, atan_yx / S_V])
            # ∂(h, v)/∂F_S, (N, 2, 3)
            J = np.zeros((geom.n, 2, 3))
            J[:, 0, 2] = 1.0 / (S_H * np.sqrt(1.0 - F[:, 2] ** 2))
            rho2 = F[:, 0] ** 2 + F[:, 1] ** 2
            J[:, 1, 0] = -F[:, 1] / (S_V * rho2)
            J[:, 1, 1] = F[:, 0] / (S_V * rho2)
            d_att = bv.left((J.reshape(-1, 3) @ M).reshape(-1, 2, 3))  # J M ∂F_B/∂δθ
            # parameter partials, formed when read (common.Partials)
            d_par: dict[str, common.PartialSource] = {
                name: (lambda k=k: np.einsum("nij,nj->ni", J, bv.v_B @ dM[k].T))
                for k, name in enumerate(common.ALIGN_NAMES)
            }
            n = geom.n
            d_par["scale_h"] = lambda: common.column(n, 2, 0, -asin_z / S_H**2)
            d_par["scale_v"] = lambda: common.column(n, 2, 1, -atan_yx / S_V**2)
            d_par["time_offset"] = lambda: np.einsum("nij,nj->ni", J, bv.d_dt @ M.T)
            valid = common.fov_square_ok(F, common.fov_rad(self.sensor))
        return common.finish(y, d_att, d_par, valid, specs)
