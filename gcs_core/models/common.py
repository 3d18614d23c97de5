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

Partials on demand: a model gives every parameter's partial (the contract), but an
estimator reads only the columns of its solve-for and consider elements, and most
parameters are held. A model may therefore register a partial as a function of no
arguments, closed over the intermediate quantities of the same ``predict`` call (value
and partials still come from one computation and cannot drift apart); :class:`Partials`
evaluates it the first time it is read.

Two products over frames, ``C v`` and the rows ``A_r × u``, have an inner dimension of
3, for which numpy's per-row overhead dominates; with numba (:data:`gcs_core.compiled.COMPILED`) they are
compiled loops, otherwise the numpy forms (same numbers to round-off).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from functools import cached_property, lru_cache
from typing import Any, overload

import numpy as np

from gcs_core import units
from gcs_core.compiled import COMPILED, jit
from gcs_core.errors import InputError
from gcs_core.frames.rotations import euler123_partials, euler123_to_dcm, rotvec_to_dcm
from gcs_core.io.types import SensorSpec
from gcs_core.models.base import Geometry, ParamSpec, Prediction

#: Fraction of the half field of view added as a margin before a frame is rejected, so
#: that alignment errors being calibrated do not throw away genuine data near the edge.
FOV_MARGIN = 0.1

ALIGN_NAMES = ("align_1", "align_2", "align_3")

_jit = jit(fastmath=False)


@_jit
def _rotate_rows(C, v, out):
    """``out_i = C_i v_i`` for (N, 3, 3) ``C`` and (N, 3) ``v``."""
    for i in range(C.shape[0]):
        v0, v1, v2 = v[i, 0], v[i, 1], v[i, 2]
        for a in range(3):
            out[i, a] = C[i, a, 0] * v0 + C[i, a, 1] * v1 + C[i, a, 2] * v2


@_jit
def _cross_rows(A, u, out):
    """``out[i, r] = A[i, r] × u_i = A[i, r] [u_i ×]`` for (N, m, 3) ``A`` and (N, 3) ``u``."""
    for i in range(A.shape[0]):
        x, y, z = u[i, 0], u[i, 1], u[i, 2]
        for r in range(A.shape[1]):
            a0, a1, a2 = A[i, r, 0], A[i, r, 1], A[i, r, 2]
            out[i, r, 0] = a1 * z - a2 * y
            out[i, r, 1] = a2 * x - a0 * z
            out[i, r, 2] = a0 * y - a1 * x


def rotate(C: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N, 3) ``C_i v_i`` for (N, 3, 3) ``C`` and (N, 3) ``v`` (module docstring)."""
    if COMPILED and C.ndim == 3 and v.ndim == 2 and C.shape[0] == v.shape[0]:
        out = np.empty(v.shape)
        _rotate_rows(C, v, out)
        return out
    return np.einsum("nij,nj->ni", C, v)


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
            raise InputError(
                f"sensor '{sensor.name}' of type '{sensor.type}' needs data-book key '{key}' ({size} values)",
                key=book_key(sensor, key),
            )
        value = default
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"'{key}' must be a list of {size} numbers", key=book_key(sensor, key)) from None
    if arr.shape[0] != size or not np.all(np.isfinite(arr)):
        raise InputError(f"'{key}' must be a list of {size} finite numbers, got {value!r}", key=book_key(sensor, key))
    return arr


@overload
def book_scalar(sensor: SensorSpec, key: str, default: float) -> float: ...
@overload
def book_scalar(sensor: SensorSpec, key: str, default: None = None) -> float | None: ...
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


def cached_parameters(model, build: Callable[[], tuple[ParamSpec, ...]]) -> tuple[ParamSpec, ...]:
    """``model.parameters()`` kept on the model: the specs are a function of its data book
    and auxiliary channels only, and the estimators ask for them at every chunk."""
    hit = getattr(model, "_specs_cache", None)
    if hit is not None and hit[0] is model.sensor and hit[1] == model.aux_channels:
        return hit[2]
    specs = build()
    model._specs_cache = (model.sensor, model.aux_channels, specs)
    return specs


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
def time_offset_spec(what: str = "the sample") -> ParamSpec:
    """``time_offset`` [s]: the time-tag offset of a sensor's samples (``what`` is of time
    t + Δt), nominal 0, a-priori σ 0.1 s, not a seed parameter, effect ``time_offset``."""
    return ParamSpec(
        "time_offset",
        "s",
        0.0,
        0.1,
        seed=False,
        effect="time_offset",
        description=f"time-tag offset: {what} is of time t + Δt",
    )


def alignment_specs(sensor: SensorSpec, *, seed: bool, sigma: float) -> tuple[ParamSpec, ...]:
    """``align_1..3`` [rad], nominal from ``alignment_deg`` (ICD §2), effect ``alignment``."""
    a_deg = (0.0, 0.0, 0.0) if sensor.alignment_deg is None else sensor.alignment_deg
    return tuple(
        ParamSpec(
            name,
            "rad",
            float(a_deg[i]) * units.DEG,
            sigma,
            seed=seed,
            effect="alignment",
            description=f"alignment angle a{i + 1} of M = T3(a3) T2(a2) T1(a1)",
        )
        for i, name in enumerate(ALIGN_NAMES)
    )


def alignment_matrix(p: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """``M = T3(a3) T2(a2) T1(a1)`` (3, 3) and ``∂M/∂a_k`` stacked (3, 3, 3), k = 1..3.

    Read-only arrays, shared between calls with the same angles (every chunk of every
    pass asks again, and an alignment is usually held).
    """
    return _alignment(*(float(p[n]) for n in ALIGN_NAMES))


@lru_cache(maxsize=256)
def _alignment(a1: float, a2: float, a3: float) -> tuple[np.ndarray, np.ndarray]:
    M, dM = euler123_to_dcm(a1, a2, a3), euler123_partials(a1, a2, a3)
    M.flags.writeable = False
    dM.flags.writeable = False
    return M, dM


# --------------------------------------------------------------------------------------
# Body vector with a time-tag offset
# --------------------------------------------------------------------------------------
#: an (N, 3) rate of a reference vector, or a function giving it when it is needed
RateSource = np.ndarray | Callable[..., np.ndarray | None] | None  # a function: called with no arguments


class BodyVector:
    """A reference vector carried into the body frame at ``t + Δt`` (module docstring).

    Attributes
    ----------
    v_B : (N, 3) body-frame vector at the shifted time.
    d_att : (N, 3, 3) ``∂v_B/∂δθ = R [u_B ×]`` (formed when read; a model multiplies it
        by its own ∂y/∂v_B with :meth:`left`, which does not need it).
    d_dt : (N, 3) ``∂v_B/∂Δt``, formed when first read (only the time-tag offset's
        partial needs it, and that effect is usually held).
    """

    def __init__(
        self,
        v_B: np.ndarray,
        u_B: np.ndarray,
        R: np.ndarray | None,
        omega: np.ndarray | None,
        C: np.ndarray,
        vdot_I: RateSource,
    ):
        self.v_B = v_B
        self._u, self._R = u_B, R
        self._omega, self._C, self._vdot = omega, C, vdot_I

    @cached_property
    def d_att(self) -> np.ndarray:
        S = _skew(self._u)
        return S if self._R is None else self._R @ S

    def left(self, A: np.ndarray) -> np.ndarray:
        """``A ∂v_B/∂δθ`` (N, m, 3) for ``A`` (m, 3) or (N, m, 3): the model's attitude
        partials, without the (N, 3, 3) skew matrices when ``R = I``.

        Row r is then ``A_r [u_B ×] = A_r × u_B``. For one ``A`` for every frame this is
        linear in ``u_B``, ``vec(A [u×]) = Σ_k u_k vec(A [e_k×])``: one (N, 3) × (3, 3m)
        product. For an ``A`` per frame, component-wise cross products.
        """
        if self._R is not None:
            return A @ self.d_att
        u = self._u
        if A.ndim == 2:
            L = np.stack([(A @ _skew(e[None])[0]).reshape(-1) for e in np.eye(3)])  # (3, 3m)
            return (u @ L).reshape(u.shape[0], A.shape[0], 3)
        out = np.empty((u.shape[0], A.shape[-2], 3))
        if COMPILED:
            _cross_rows(A, u, out)
            return out
        x, y, z = u[:, None, 0], u[:, None, 1], u[:, None, 2]
        a0, a1, a2 = A[..., 0], A[..., 1], A[..., 2]
        # (a × u) = (a1 z − a2 y, a2 x − a0 z, a0 y − a1 x)
        np.subtract(a1 * z, a2 * y, out=out[:, :, 0])
        np.subtract(a2 * x, a0 * z, out=out[:, :, 1])
        np.subtract(a0 * y, a1 * x, out=out[:, :, 2])
        return out

    @cached_property
    def d_dt(self) -> np.ndarray:
        """``−ω_B × v_B + R C v̇_I`` (N, 3)."""
        with np.errstate(all="ignore"):
            out = np.zeros_like(self.v_B) if self._omega is None else -np.cross(self._omega, self.v_B)
            vdot = _rate(self._vdot)
            if vdot is not None:
                RC = self._C if self._R is None else self._R @ self._C
                out += np.einsum("nij,nj->ni", RC, vdot)
        return out


def _rate(src: RateSource) -> np.ndarray | None:
    """The (N, 3) rate ``src`` holds or gives; None when it gives none (a magnetometer
    without a field model: the field's motion is then left out, not made NaN)."""
    rate = src() if callable(src) else src
    return None if rate is None else np.asarray(rate, dtype=float)


def body_vector(geom: Geometry, v_I: np.ndarray, dt: float, vdot_I: RateSource = None) -> BodyVector:
    """``v_B(t + Δt) = R(Δt) C (v_I + Δt v̇_I)`` and its partials (module docstring).

    ``vdot_I`` may be a function of no arguments: it is then called only when needed
    (``Δt ≠ 0``, or ``d_dt`` read). With ``Δt = 0`` (the usual case: the time-tag offset
    held at zero) ``R = I`` exactly and the products with it are skipped; the numbers are
    the same.
    """
    if geom.C_BI is None:
        raise ValueError("this model needs the attitude C_BI in the geometry")
    C = np.asarray(geom.C_BI, dtype=float)
    v_I = np.asarray(v_I, dtype=float)
    w_I = v_I
    if dt != 0.0 and vdot_I is not None:
        vdot_I = _rate(vdot_I)
        if vdot_I is not None:
            w_I = v_I + dt * vdot_I
    u_B = rotate(C, w_I)  # C (v_I + Δt v̇_I)
    omega = None
    if geom.omega_B is not None:
        omega = np.broadcast_to(np.asarray(geom.omega_B, dtype=float), u_B.shape)
    if omega is None or dt == 0.0:
        return BodyVector(u_B, u_B, None, omega, C, vdot_I)
    R = rotvec_to_dcm(omega * dt)  # exp(−[ω Δt ×])
    v_B = rotate(R, u_B)
    return BodyVector(v_B, u_B, R, omega, C, vdot_I)  # ∂v_B/∂δθ = R [u_B ×]


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
    """(N,) ``S_Sx > 0`` and both projected angles within the (margined) half FOV.

    With ``S_Sx > 0`` the projected angle is ``atan(S_Sy / S_Sx)``, below a limit under
    90° exactly when ``|S_Sy| ≤ tan(limit) S_Sx`` (no arctangent per frame).
    """
    x = S_S[:, 0]
    ok = x > 0.0
    if fov is not None:
        lim = fov * (1.0 + FOV_MARGIN)
        if lim < 0.5 * np.pi:
            edge = np.tan(lim) * x
            ok &= np.abs(S_S[:, 1]) <= edge
            ok &= np.abs(S_S[:, 2]) <= edge
    return ok


#: a partial as given by a model: an array broadcastable to (N, m), or a function giving it
PartialSource = np.ndarray | Callable[..., np.ndarray]  # a function: called with no arguments


class Partials(Mapping):
    """A prediction's parameter partials, ``name -> (N, m)`` (module docstring).

    Each entry is an array or a function of no arguments; a function is evaluated the
    first time its entry is read (under ``np.errstate(all="ignore")``, like the model's
    own arithmetic). Every entry is then broadcast to (N, m) and, when the prediction has
    invalid frames ``bad`` (N,), copied with those rows set to NaN.
    """

    def __init__(self, entries: Mapping[str, PartialSource], shape: tuple[int, int], bad: np.ndarray | None = None):
        self._entries = dict(entries)
        self._shape = tuple(shape)
        self._bad = bad
        self._done: dict[str, np.ndarray] = {}

    def __getitem__(self, name: str) -> np.ndarray:
        out = self._done.get(name)
        if out is None:
            src = self._entries[name]
            with np.errstate(all="ignore"):
                d = np.asarray(src() if callable(src) else src, dtype=float)
            if self._bad is None:
                out = d if d.shape == self._shape else np.broadcast_to(d, self._shape)
            else:
                out = np.array(np.broadcast_to(d, self._shape), dtype=float)
                out[self._bad] = np.nan
            self._done[name] = out
        return out

    def __contains__(self, name) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)


def column(n: int, m: int, i: int, value) -> np.ndarray:
    """(n, m) zeros with column ``i`` set to ``value`` (a partial touching one component)."""
    out = np.zeros((n, m))
    out[:, i] = value
    return out


def finish(
    y: np.ndarray,
    d_att: np.ndarray,
    d_par: Mapping[str, PartialSource],
    valid: np.ndarray,
    specs: tuple[ParamSpec, ...],
    d2_par: Mapping[tuple[str, str], tuple[int, Any]] | None = None,
) -> Prediction:
    """Check that every parameter has a partial, NaN-out invalid frames, build the Prediction
    (partials given as functions are formed when read, :class:`Partials`); ``d2_par`` the
    optional second partials (:attr:`Prediction.d2_par`), kept as given."""
    missing = [p.name for p in specs if p.name not in d_par]
    if missing:  # a bug in the model, not bad input
        raise RuntimeError(f"model gives no partials for {missing}")
    valid = np.array(valid, dtype=bool)
    for c in range(y.shape[1]):  # column by column: a reduction over axis 1 is slow
        valid &= np.isfinite(y[:, c])
    bad = ~valid
    entries = {p.name: d_par[p.name] for p in specs}
    if not bad.any():
        # nothing to NaN out: the model's own arrays are the prediction (no copies)
        y = np.asarray(y, dtype=float)
        return Prediction(
            y=y,
            d_att=np.asarray(d_att, dtype=float),
            d_par=Partials(entries, y.shape),
            valid=valid,
            d2_par=dict(d2_par or {}),
        )
    y = np.array(y, dtype=float)
    d_att = np.array(d_att, dtype=float)
    y[bad] = np.nan
    d_att[bad] = np.nan
    return Prediction(y=y, d_att=d_att, d_par=Partials(entries, y.shape, bad), valid=valid, d2_par=dict(d2_par or {}))


def component_values(entry, n: int) -> tuple[int, np.ndarray]:
    """``(component, (n,) values)`` of a component-sparse entry ``(component, source)``
    (``Prediction.d2_par``, ``HeldPrediction``): the source is an array, a scalar or a
    function of no arguments giving one."""
    c, src = entry
    with np.errstate(all="ignore"):
        v = src() if callable(src) else src
    return c, np.broadcast_to(np.asarray(v, dtype=float), (n,))


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
