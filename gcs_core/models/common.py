"""Pieces shared by the observation models: data-book access, sensor alignment, time tags.

Sensor alignment (ICD §2, seed Eq 4-31 and the ∂[M]/∂α, ∂β, ∂δ matrices after it)::

    v_S = M v_B,    M = T3(a3) T2(a2) T1(a1)

Its partials come from :func:`gcs_core.frames.rotations.euler123_partials` (the same
Euler 1-2-3 sequence as the attitude, Eq 4-22).

Time-tag offset (extended physics, effect ``time_offset``). A measurement stamped ``t``
is taken to sample the scene at ``t + Δt``. Over the short ``Δt`` the body rate ω_B is
held constant and a reference vector moves linearly in GCI, so the body-frame vector is
exactly::

    v_B(t + Δt) = R(Δt) C (v_I + Δt v̇_I),    R(Δt) = exp(−[ω_B Δt ×]) = rotvec_to_dcm(ω_B Δt)
    ∂v_B/∂Δt    = −ω_B × v_B(t + Δt) + R C v̇_I
    ∂v_B/∂δθ    = R [(C (v_I + Δt v̇_I)) ×]           (attitude error, base.py convention)

(``Ċ = −[ω×] C`` for ``C`` mapping GCI to body.) Stars are fixed in GCI (``v̇_I = 0``);
the Sun direction moves by about 2e-7 rad/s, which is neglected for the Sun sensors;
the magnetometer supplies ``Ḃ_I`` from the field model. Without ``omega_B`` in the
geometry the rotation term is zero.

Invalid frames: every model computes under ``np.errstate(all="ignore")`` and then sets
``y`` and every partial of a frame with ``valid == False`` to NaN, so that a frame the
model cannot describe can never be used by mistake.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from gcs_core import units
from gcs_core.errors import InputError
from gcs_core.frames.rotations import euler123_partials, euler123_to_dcm, rotvec_to_dcm, skew
from gcs_core.models.base import Geometry, ParamSpec, Prediction
from gcs_core.sidp.types import SensorSpec

#: Fraction of the half field of view added as a margin before a frame is rejected, so
#: that alignment errors being calibrated do not throw away genuine data near the edge.
FOV_MARGIN = 0.1

ALIGN_NAMES = ("align_1", "align_2", "align_3")


# --------------------------------------------------------------------------------------
# Data-book access
# --------------------------------------------------------------------------------------
def book_key(sensor: SensorSpec, key: str) -> str:
    """The dotted key used in messages, e.g. ``FSS1.coeff_alpha``."""
    return f"{sensor.name}.{key}"


def book_vector(sensor: SensorSpec, key: str, size: int, default=None) -> np.ndarray:
    """Data-book value ``key`` as a float vector of length ``size``.

    A scalar is not broadcast: the ICD gives vectors explicitly. ``default`` (a sequence)
    is used when the key is absent; without a default the key is required.
    """
    value = sensor.get(key, None)
    if value is None:
        if default is None:
            raise InputError(f"sensor '{sensor.name}' of type '{sensor.type}' needs data-book key "
                             f"'{key}' ({size} values)", key=book_key(sensor, key))
        value = default
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"'{key}' must be a list of {size} numbers", key=book_key(sensor, key)) from None
    if arr.shape[0] != size or not np.all(np.isfinite(arr)):
        raise InputError(f"'{key}' must be a list of {size} finite numbers, got {value!r}",
                         key=book_key(sensor, key))
    return arr


def book_scalar(sensor: SensorSpec, key: str, default: float | None = None) -> float | None:
    """Data-book value ``key`` as a float (``default`` when absent)."""
    value = sensor.get(key, None)
    if value is None:
        return default
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise InputError(f"'{key}' must be a number, got {value!r}", key=book_key(sensor, key)) from None
    if not np.isfinite(out):
        raise InputError(f"'{key}' must be finite", key=book_key(sensor, key))
    return out


def noise_value(sensor: SensorSpec) -> float:
    """The ICD ``noise`` key (required by every type but the gyro)."""
    if sensor.noise is None:
        raise InputError(f"sensor '{sensor.name}' needs a 'noise' value", key=book_key(sensor, "noise"))
    if not sensor.noise > 0.0:
        raise InputError("'noise' must be positive", key=book_key(sensor, "noise"))
    return float(sensor.noise)


def fov_rad(sensor: SensorSpec) -> float | None:
    """Half field of view [rad] from ``fov_deg``, or None when the book gives none."""
    value = book_scalar(sensor, "fov_deg")
    if value is None:
        return None
    if not 0.0 < value < 90.0:
        raise InputError("'fov_deg' (half width) must lie in (0, 90)", key=book_key(sensor, "fov_deg"))
    return value * units.DEG


def merged_params(specs: tuple[ParamSpec, ...], params: Mapping[str, float]) -> dict[str, float]:
    """Data-book values overridden by ``params``; an unknown name is a programming error."""
    values = {p.name: float(p.nominal) for p in specs}
    unknown = set(params) - set(values)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)}; model has {sorted(values)}")
    values.update({k: float(v) for k, v in params.items()})
    return values


# --------------------------------------------------------------------------------------
# Alignment
# --------------------------------------------------------------------------------------
def alignment_specs(sensor: SensorSpec, *, seed: bool, sigma: float) -> tuple[ParamSpec, ...]:
    """``align_1..3`` [rad], nominal from ``alignment_deg`` (ICD §2), effect ``alignment``."""
    a_deg = (0.0, 0.0, 0.0) if sensor.alignment_deg is None else sensor.alignment_deg
    return tuple(
        ParamSpec(name, "rad", float(a_deg[i]) * units.DEG, sigma, seed=seed, effect="alignment",
                  description=f"alignment angle a{i + 1} of M = T3(a3) T2(a2) T1(a1)")
        for i, name in enumerate(ALIGN_NAMES))


def alignment_matrix(p: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """``M = T3(a3) T2(a2) T1(a1)`` (3, 3) and ``∂M/∂a_k`` stacked (3, 3, 3), k = 1..3."""
    a1, a2, a3 = (p[n] for n in ALIGN_NAMES)
    return euler123_to_dcm(a1, a2, a3), euler123_partials(a1, a2, a3)


# --------------------------------------------------------------------------------------
# Body vector with a time-tag offset
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BodyVector:
    """A reference vector carried into the body frame at ``t + Δt`` (module docstring).

    Attributes
    ----------
    v_B : (N, 3) body-frame vector at the shifted time.
    d_att : (N, 3, 3) ``∂v_B/∂δθ``.
    d_dt : (N, 3) ``∂v_B/∂Δt``.
    """

    v_B: np.ndarray
    d_att: np.ndarray
    d_dt: np.ndarray


def body_vector(geom: Geometry, v_I: np.ndarray, dt: float, vdot_I: np.ndarray | None = None) -> BodyVector:
    """``v_B(t + Δt) = R(Δt) C (v_I + Δt v̇_I)`` and its partials (module docstring).

    With ``Δt = 0`` (the usual case: the time-tag offset held at zero) ``R = I`` exactly and
    the products with it are skipped; the numbers are the same.
    """
    if geom.C_BI is None:
        raise ValueError("this model needs the attitude C_BI in the geometry")
    C = np.asarray(geom.C_BI, dtype=float)
    v_I = np.asarray(v_I, dtype=float)
    w_I = v_I if vdot_I is None else v_I + dt * vdot_I
    u_B = np.einsum("nij,nj->ni", C, w_I)                      # C (v_I + Δt v̇_I)
    identity = geom.omega_B is None or dt == 0.0
    if geom.omega_B is None:
        v_B = u_B
        d_dt = np.zeros_like(v_B)
    else:
        omega = np.broadcast_to(np.asarray(geom.omega_B, dtype=float), u_B.shape)
        if identity:
            v_B = u_B
        else:
            R = rotvec_to_dcm(omega * dt)                      # exp(−[ω Δt ×])
            v_B = np.einsum("nij,nj->ni", R, u_B)
        d_dt = -np.cross(omega, v_B)                           # −ω × v_B
    if vdot_I is not None:
        d_dt = d_dt + np.einsum("nij,nj->ni", C if identity else R @ C, vdot_I)    # + R C v̇_I
    d_att = _skew(u_B) if identity else R @ skew(u_B)          # R [u_B ×]
    return BodyVector(v_B, d_att, d_dt)


def _skew(v: np.ndarray) -> np.ndarray:
    """``[v×]`` (N, 3, 3) written in place (the values of :func:`~gcs_core.frames.rotations.skew`)."""
    out = np.zeros(v.shape[:-1] + (3, 3))
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    out[..., 0, 1] = -z
    out[..., 0, 2] = y
    out[..., 1, 0] = z
    out[..., 1, 2] = -x
    out[..., 2, 0] = -y
    out[..., 2, 1] = x
    return out


# --------------------------------------------------------------------------------------
# Small helpers for the predict() implementations
# --------------------------------------------------------------------------------------
def fov_square_ok(S_S: np.ndarray, fov: float | None) -> np.ndarray:
    """(N,) ``S_Sx > 0`` and both projected angles within the (margined) half FOV."""
    ok = S_S[:, 0] > 0.0
    if fov is not None:
        lim = fov * (1.0 + FOV_MARGIN)
        ok &= np.abs(np.arctan2(S_S[:, 1], S_S[:, 0])) <= lim
        ok &= np.abs(np.arctan2(S_S[:, 2], S_S[:, 0])) <= lim
    return ok


def finish(y: np.ndarray, d_att: np.ndarray, d_par: dict[str, np.ndarray], valid: np.ndarray,
           specs: tuple[ParamSpec, ...]) -> Prediction:
    """Check that every parameter has a partial, NaN-out invalid frames, build the Prediction."""
    missing = [p.name for p in specs if p.name not in d_par]
    if missing:  # a bug in the model, not bad input
        raise RuntimeError(f"model gives no partials for {missing}")
    valid = np.asarray(valid, dtype=bool) & np.all(np.isfinite(y), axis=1)
    bad = ~valid
    if not bad.any():
        # nothing to NaN out: the model's own arrays are the prediction (no copies)
        y = np.asarray(y, dtype=float)
        out = {}
        for p in specs:
            d = np.asarray(d_par[p.name], dtype=float)
            out[p.name] = d if d.shape == y.shape else np.broadcast_to(d, y.shape)
        return Prediction(y=y, d_att=np.asarray(d_att, dtype=float), d_par=out, valid=valid)
    y = np.array(y, dtype=float)
    d_att = np.array(d_att, dtype=float)
    out = {}
    for p in specs:
        d = np.array(np.broadcast_to(d_par[p.name], y.shape), dtype=float)
        d[bad] = np.nan
        out[p.name] = d
    y[bad] = np.nan
    d_att[bad] = np.nan
    return Prediction(y=y, d_att=d_att, d_par=out, valid=valid)


def unit_rows(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row-normalized vectors and their norms, ``(v/|v|, |v|)``."""
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v, axis=-1)
    return v / n[..., None], n


def frames_of(vec: np.ndarray, n: int) -> np.ndarray:
    """A (3,) or (N, 3) vector broadcast to (N, 3), as a float copy."""
    return np.array(np.broadcast_to(np.asarray(vec, dtype=float), (n, 3)), dtype=float)


def spin_axis_unit(geom: Geometry) -> tuple[np.ndarray, np.ndarray]:
    """``(Â, P)``: unit spin axis (N, 3) and ``∂Â/∂a = (I − ÂÂᵀ)/|a|`` (N, 3, 3)."""
    if geom.spin_axis_I is None:
        raise ValueError("this spinning-mission model needs spin_axis_I in the geometry")
    a = frames_of(geom.spin_axis_I, geom.n)
    A, norm = unit_rows(a)
    P = (np.eye(3) - np.einsum("ni,nj->nij", A, A)) / norm[:, None, None]
    return A, P
