"""Three-axis magnetometer (TAM), seed §4.2.5, Eq 4-27 and 4-28; ICD §5 ``magnetometer``.

Observation model, seed form (Eq 4-27) and the extended form GCS offers::

    B_S = M C B_I + b                                        (Eq 4-27, state Eq 4-28)
    B_S = (I + D) M B_B(t + Δt) + b + Σ_ch k_ch aux_ch       (extended)

with ``B_B(t + Δt) = R(Δt) C (B_I + Δt Ḃ_I)`` (see :mod:`gcs_core.models.common`),
``D`` symmetric: its diagonal the scale-factor errors ``scale_x/y/z`` and its
off-diagonal the non-orthogonality ``nonorth_xy/xz/yz``; ``k_ch`` the contamination of
auxiliary channel ``ch`` (torquer dipole, temperature, ...) per sensor axis.

Partials (Eq 4-28 and after; attitude per base.py)::

    ∂y/∂b_i   = e_i
    ∂y/∂δθ    = (I + D) M R [u_B ×],          u_B = C (B_I + Δt Ḃ_I)
    ∂y/∂a_k   = (I + D) ∂M/∂a_k B_B
    ∂y/∂D_ij  = e_i (M B_B)_j   (symmetric pairs summed)
    ∂y/∂k_ch,i = e_i aux_ch
    ∂y/∂Δt    = (I + D) M (−ω_B × B_B + R C Ḃ_I)

Constant field (physics ``field_model = "constant"``, a laboratory on the ground,
docs/ground.md): ``B_I`` is one unknown vector of the reference frame, the shared state
elements ``field.B_x/y/z`` [nT] (solve-for by default, nominal 0, a-priori σ
:data:`FIELD_SIGMA_NT`), with ``∂y/∂B_I = (I + D) M R C`` and ``Ḃ_I = 0``.

Field gradient (effect ``field_gradient``, constant field only): a room's field is not
uniform over the decimetres a unit is carried near steel and wiring. When the mission's
aux channels hold the sensor's position in the reference frame, :data:`POSITION_CHANNELS`
[m, from a fixed point of the room], the field at the sensor is the first-order Taylor
expansion about that point::

    B_I(p) = B_0 + G p,   G = [[G_xx, G_xy, G_xz], [G_xy, G_yy, G_yz], [G_xz, G_yz, −G_xx − G_yy]]

``G`` symmetric (curl-free: no current in the volume, ∇×B = 0) and trace-free (∇·B = 0),
hence five elements ``field.G_xx/xy/xz/yy/yz`` [nT/m] (Jackson, Classical
Electrodynamics, 3rd ed., ch. 5: ∇·B = 0, and where no current flows ∇×B = 0, so
B = −∇Φ_M with ∇²Φ_M = 0).
Partials ``∂y/∂G_ab = (I + D) M R C (∂G/∂G_ab) p``. The position channels feed only the
gradient, not the contamination terms. The position is held over the time offset (the
field a unit carried at 1 m/s sees change over 10 ms by G·1 cm, ~20 nT at 2 µT/m).

``Ḃ_I`` (the field's rate along the orbit) is taken, in this order, from
``geom.extra["B_I_dot"]`` (N, 3) [nT/s] when the caller has precomputed it, else from a
central difference of ``geom.field_model`` at ``(t ± h, r ± v h)`` with h = 1 s (two
extra field evaluations per call), else zero (documented loss: then ``time_offset``
only sees the attitude motion).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np

from gcs_core.display import per_channel
from gcs_core.errors import InputError
from gcs_core.models import common
from gcs_core.models.base import Geometry, ObservationModel, ParamSpec, Prediction

log = logging.getLogger(__name__)

AXES = ("x", "y", "z")
#: (name, i, j) of the symmetric non-orthogonality entries D_ij = D_ji.
NONORTH = (("nonorth_xy", 0, 1), ("nonorth_xz", 0, 2), ("nonorth_yz", 1, 2))
#: step [s] of the central difference giving Ḃ_I from the field model.
FIELD_RATE_STEP_S = 1.0
#: a-priori 1-sigma of each component of an unknown constant field [nT] (the Earth's
#: field is below 7e4 nT; a laboratory may distort it by tens of percent)
FIELD_SIGMA_NT = 1e5
#: aux channels holding the sensor's position in the reference frame [m] (the gradient's lever)
POSITION_CHANNELS = ("pos_x", "pos_y", "pos_z")
#: (name, ∂G/∂G_ab) of the five free elements of a symmetric trace-free gradient
GRADIENT = (
    ("xx", ((1, 0, 0), (0, 0, 0), (0, 0, -1))),
    ("xy", ((0, 1, 0), (1, 0, 0), (0, 0, 0))),
    ("xz", ((0, 0, 1), (0, 0, 0), (1, 0, 0))),
    ("yy", ((0, 0, 0), (0, 1, 0), (0, 0, -1))),
    ("yz", ((0, 0, 0), (0, 0, 1), (0, 1, 0))),
)
#: a-priori 1-sigma of each gradient element [nT/m] (a few µT/m within a metre of a steel
#: bench; 1e5 nT/m leaves the data to decide)
GRADIENT_SIGMA_NT_PER_M = 1e5


class MagnetometerModel(ObservationModel):
    """Three-axis magnetometer, Eq 4-27: ``B_S = (I + D) M C B_I + b + K·aux``."""

    type_name = "magnetometer"
    columns = ("bx", "by", "bz")
    components = ("bx", "by", "bz")
    unit = "nT"
    attitude_kind = "three_axis"
    book_keys = ("bias",)

    def __init__(self, sensor, *, aux_channels: tuple[str, ...] = (), constant_field: bool = False):
        super().__init__(sensor, aux_channels=aux_channels)
        self.constant_field = bool(constant_field)
        #: the field gradient is a parameter (constant field and the position channels present)
        self.gradient = self.constant_field and all(c in self.aux_channels for c in POSITION_CHANNELS)

    @property
    def contamination_channels(self) -> tuple[str, ...]:
        """The aux channels with contamination terms (not the gradient's position)."""
        if not self.gradient:
            return self.aux_channels
        return tuple(c for c in self.aux_channels if c not in POSITION_CHANNELS)

    def parameters(self) -> tuple[ParamSpec, ...]:
        return common.cached_parameters(self, self._parameters)

    def unavailable_effects(self) -> dict[str, str]:
        if self.gradient:
            return {}
        missing = [c for c in POSITION_CHANNELS if c not in self.aux_channels]
        needs = [] if self.constant_field else ['physics field_model = "constant" (a laboratory field)']
        if missing:
            needs.append(f"the sensor's position as aux channels {', '.join(missing)} [m] in aux.csv")
        return {"field_gradient": "needs " + " and ".join(needs)}

    def _parameters(self) -> tuple[ParamSpec, ...]:
        bias = common.book_vector(self.sensor, "bias", 3, default=(0.0, 0.0, 0.0))
        specs = [
            ParamSpec(
                f"bias_{ax}",
                "nT",
                float(bias[i]),
                200.0,
                seed=True,
                effect="bias",
                description=f"magnetometer bias along sensor {ax} (Eq 4-27)",
            )
            for i, ax in enumerate(AXES)
        ]
        specs += common.alignment_specs(self.sensor, seed=False, sigma=0.02)
        specs += [
            ParamSpec(
                f"scale_{ax}",
                "1",
                0.0,
                0.01,
                seed=False,
                effect="scale",
                description=f"scale-factor error of sensor {ax} (diagonal of D)",
            )
            for ax in AXES
        ]
        specs += [
            ParamSpec(
                name,
                "1",
                0.0,
                0.01,
                seed=False,
                effect="nonorthogonality",
                description=f"non-orthogonality D_{name[-2:]} = D_{name[-1:]}{name[-2]}",
            )
            for name, _, _ in NONORTH
        ]
        for ch in self.contamination_channels:
            specs += [
                ParamSpec(
                    f"contam_{ch}_{ax}",
                    per_channel("nT", ch),  # nT/(A m²) for a torquer channel (gcs_core.display)
                    0.0,
                    10.0,
                    seed=False,
                    effect=f"contamination_{ch}",
                    description=f"field along sensor {ax} per unit of aux channel '{ch}'",
                )
                for ax in AXES
            ]
        specs.append(common.time_offset_spec())
        if self.constant_field:
            specs += [
                ParamSpec(
                    f"field_{ax}",
                    "nT",
                    0.0,
                    FIELD_SIGMA_NT,
                    seed=True,
                    effect="field",
                    description=f"constant reference field along reference {ax} (field_model = constant)",
                    element=f"field.B_{ax}",
                )
                for ax in AXES
            ]
        if self.gradient:
            specs += [
                ParamSpec(
                    f"gradient_{ab}",
                    "nT/m",
                    0.0,
                    GRADIENT_SIGMA_NT_PER_M,
                    seed=False,
                    effect="field_gradient",
                    element=f"field.G_{ab}",
                    description=f"field gradient ∂B_{ab[0]}/∂{ab[1]} of the reference frame (symmetric, trace-free)",
                )
                for ab, _ in GRADIENT
            ]
        return tuple(specs)

    def sigma(self) -> np.ndarray:
        return np.full(3, common.noise_value(self.sensor))

    def _field_rate(self, geom: Geometry) -> np.ndarray | None:
        """Ḃ_I [nT/s] (N, 3), see the module docstring for the order of sources."""
        if "B_I_dot" in geom.extra:
            return np.asarray(geom.extra["B_I_dot"], dtype=float)
        if geom.field_model is None or geom.r_I is None or geom.v_I is None:
            log.debug("%s: no field model; time_offset partial ignores the field's motion", self.name)
            return None
        h = FIELD_RATE_STEP_S
        t = np.asarray(geom.t, dtype=float)
        r, v = np.asarray(geom.r_I, dtype=float), np.asarray(geom.v_I, dtype=float)
        b_plus = np.asarray(geom.field_model(t + h, r + v * h), dtype=float)
        b_minus = np.asarray(geom.field_model(t - h, r - v * h), dtype=float)
        return (b_plus - b_minus) / (2.0 * h)

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """Eq 4-27 (extended form) at N frames: y (N, 3), d_att (N, 3, 3), d_par (N, 3).

        The parameter partials are registered as functions (formed when read,
        :class:`~gcs_core.models.common.Partials`); an auxiliary channel whose three
        contamination coefficients are all zero does not enter ``y`` (its term is zero).
        """
        specs = self.parameters()
        p = common.merged_params(specs, params)
        n = geom.n
        B_I = geom.B_I
        rate: common.RateSource = lambda: self._field_rate(geom)
        if self.constant_field:
            B_I = np.broadcast_to(np.array([p["field_x"], p["field_y"], p["field_z"]]), (n, 3))
            rate = None
            if self.gradient:
                pos = np.column_stack([np.asarray(geom.aux[c], dtype=float) for c in POSITION_CHANNELS])
                G = sum((p[f"gradient_{ab}"] * np.asarray(dG, dtype=float) for ab, dG in GRADIENT), np.zeros((3, 3)))
                B_I = B_I + pos @ G.T
        if B_I is None:
            raise ValueError("magnetometer model needs B_I in the geometry")
        M, dM = common.alignment_matrix(p)
        D = np.diag([p["scale_x"], p["scale_y"], p["scale_z"]])
        for name, i, j in NONORTH:
            D[i, j] = D[j, i] = p[name]
        ID = np.eye(3) + D
        IDM = ID @ M
        unit = np.eye(3)
        for ch in self.aux_channels:
            if ch not in geom.aux:
                raise InputError(
                    f"auxiliary channel '{ch}' is not in the aux data", key=common.book_key(self.sensor, "aux")
                )
        with np.errstate(all="ignore"):
            bv = common.body_vector(geom, B_I, p["time_offset"], rate)
            w = bv.v_B @ M.T  # M B_B (N, 3)
            y = w @ ID.T
            y += np.array([p["bias_x"], p["bias_y"], p["bias_z"]])
            d_par: dict[str, common.PartialSource] = {}
            for i, ax in enumerate(AXES):
                d_par[f"bias_{ax}"] = np.broadcast_to(unit[i], (n, 3))  # e_i
                d_par[f"scale_{ax}"] = lambda i=i: common.column(n, 3, i, w[:, i])
            for name, i, j in NONORTH:

                def nonorth(i=i, j=j):
                    s_ = common.column(n, 3, i, w[:, j])
                    s_[:, j] = w[:, i]
                    return s_

                d_par[name] = nonorth
            for k, name in enumerate(common.ALIGN_NAMES):
                d_par[name] = lambda k=k: bv.v_B @ (ID @ dM[k]).T
            for ch in self.contamination_channels:
                k_ch = np.array([p[f"contam_{ch}_{ax}"] for ax in AXES])
                if np.any(k_ch != 0.0):
                    y += np.asarray(geom.aux[ch], dtype=float)[:, None] * k_ch
                for i, ax in enumerate(AXES):
                    d_par[f"contam_{ch}_{ax}"] = lambda ch=ch, i=i: common.column(
                        n, 3, i, np.asarray(geom.aux[ch], dtype=float)
                    )
            d_par["time_offset"] = lambda: bv.d_dt @ IDM.T
            if self.constant_field:
                C = np.asarray(geom.C_BI, dtype=float)
                RC = C if bv._R is None else bv._R @ C
                for k, ax in enumerate(AXES):
                    d_par[f"field_{ax}"] = lambda k=k: RC[:, :, k] @ IDM.T  # (I+D) M R C e_k
                for ab, dG_ab in GRADIENT if self.gradient else ():
                    dG = np.asarray(dG_ab, dtype=float)
                    d_par[f"gradient_{ab}"] = lambda dG=dG: (
                        np.einsum("nij,nj->ni", RC, pos @ dG.T) @ IDM.T
                    )  # (I+D) M R C ∂G p
            d_att = bv.left(IDM)
        return common.finish(y, d_att, d_par, np.ones(n, dtype=bool), specs)
