"""Attitude as a function of state elements, with partials (seed §4.1, §4.2.7).

Three providers, one per kind of mission:

* :class:`ReferenceAttitude` — three-axis, constant roll/pitch/yaw relative to the
  reference frame (inertial, Earth- or Sun-pointing): ``C(t) = B(φ, θ, ψ) A(t)``
  (Eq 4-4, 4-6, 4-7). Elements ``att.roll``, ``att.pitch``, ``att.yaw``.
* :class:`GyroAttitude` — three-axis, attitude carried by the gyros from the
  roll/pitch/yaw at the reference time ``t_ref`` (Eq 4-32, 4-33, 4-38). Elements
  ``att.roll/pitch/yaw`` at ``t_ref`` plus the gyro's own parameters (Eq 4-37).
  It lives in :mod:`gcs_core.problem.gyro_attitude`.
* :class:`SpinAttitude` — spin-axis right ascension and declination (Eq 4-2).
  Elements ``att.ra``, ``att.dec``.

Two more providers serve the predictor (:mod:`gcs_core.predictor`):

* :class:`ManeuverAttitude` — gyro-free three-axis attitude whose roll/pitch/yaw follow
  a *known* maneuver profile: ``(φ, θ, ψ)(t) = x + Δ(t)``, elements ``x`` = the
  ``att.*`` values at ``start``; ``∂δθ/∂x`` is Eq 4-22 at the angles of each time.
* :class:`BodyErrorAttitude` — a fixed nominal attitude whose elements are the body
  error angles themselves (``∂δθ/∂x = I``); the covariance recursion of Eq 3-4 uses it
  to obtain the observation partials with respect to the current attitude error.

Every provider answers :meth:`evaluate` with the attitude at the requested times and
the partials of the body-frame attitude error ``δθ`` (three-axis, the convention of
:mod:`gcs_core.models.base`) or of the spin axis ``Â`` (spinning) with respect to its
elements. The estimator chains them with the sensor models' ``d_att``.

Error propagation through the gyros (first order in ``δω Δt``)::

    δθ_k = Φ_k δθ_{k-1} + δω_k Δ_k,   Φ_k = C_k C_{k-1}ᵀ
    ⇒ C_kᵀ δθ_k = C_0ᵀ δθ_0 + Σ_{j≤k} C_jᵀ δω_j Δ_j              (a cumulative sum)

with ``δω = ∂ω/∂p δp`` from ``ω = Mᵀ (G⁻¹ y − b)`` (Eq 4-32 inverted).

For the chunked linearization every provider also answers :meth:`frames` with a
:class:`FrameAttitude`, whose :meth:`~FrameAttitude.chain` forms ``∂y/∂δθ · ∂δθ/∂x``
directly; the gyro-carried attitude is propagated block by block with a carry, so its
memory does not grow with the span.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from gcs_core.compiled import COMPILED
from gcs_core.frames.reference import earth_pointing_rate, reference_dcm, spin_axis, spin_axis_partials
from gcs_core.frames.rotations import dcm_to_euler123, euler123_partials, euler123_to_dcm
from gcs_core.models.base import ParamSpec
from gcs_core.problem import kernels as kernels
from gcs_core.units import DEG

RPY = ("att.roll", "att.pitch", "att.yaw")
#: gyro bias instability, modelled as a bias changing linearly over the span (rad/s²)
BIAS_RATE_NAMES = ("bias_rate_x", "bias_rate_y", "bias_rate_z")
RADEC = ("att.ra", "att.dec")
#: body error angle element names of :class:`BodyErrorAttitude`
ERR = ("err.x", "err.y", "err.z")
#: gyro rows per block of the propagation (bounded memory, see GyroAttitude)
BLOCK_KNOTS = 16_384


@dataclass(frozen=True)
class AttitudeEval:
    """Attitude at N times and its partials.

    Attributes
    ----------
    C_BI : (N, 3, 3) GCI-to-body (three-axis) or None.
    spin_axis_I : (3,) spin axis (spinning) or None.
    names : element names the partials refer to.
    J : (N, 3, k) ``∂δθ/∂x`` (three-axis) or ``∂Â/∂x`` (spinning), k = len(names).
    omega_B : (N, 3) body rate at the times (three-axis with gyros) or None.
    """

    C_BI: np.ndarray | None
    spin_axis_I: np.ndarray | None
    names: tuple[str, ...]
    J: np.ndarray
    omega_B: np.ndarray | None = None


class FrameAttitude:
    """Attitude at the N frames of one chunk, its partials kept factored.

    What the chunked linearization needs from an attitude provider: ``C_BI`` (or the
    spin axis), ``omega_B`` and :meth:`chain`, the product ``D ∂δθ/∂x`` of a model's
    attitude partials ``D`` (N, m, 3) with the attitude partials over some elements,
    formed without building the (N, 3, k) Jacobian when the provider knows a cheaper
    order (the gyro-carried attitude, module docstring)::

        ∂δθ/∂(φ, θ, ψ) = C M_a,    ∂δθ/∂p = C X + W s                    (M_a = C_0ᵀ J_0)

    with ``X = E_k`` at a frame on gyro knot ``k`` (no ``W s`` term) and ``X = E_{k−1}``
    elsewhere in interval ``k``.

    Attributes
    ----------
    C_BI : (N, 3, 3) or None; spin_axis_I : (3,) or None; omega_B : (N, 3) or None.
    names : element names of the partials.
    C_chain : (N, 3, 3) the attitude the factored partials ``C X`` are taken at, when it
        is not ``C_BI``: a correction applied on top of a provider's attitude
        (``C_BI = C_chain exp(−[α×])``, the whole-span knots) leaves the body-frame
        partials of the statics those of the provider, ``C_chain X``, not ``C_BI X``.
    """

    __slots__ = ("C_BI", "spin_axis_I", "omega_B", "names", "_J", "_gyro", "C_chain")

    def __init__(self, C_BI, spin_axis_I, omega_B, names, J=None, gyro=None, C_chain=None):
        self.C_BI = C_BI
        self.spin_axis_I = spin_axis_I
        self.omega_B = omega_B
        self.names = tuple(names)
        self._J = J
        self._gyro = gyro
        self.C_chain = C_BI if C_chain is None else C_chain

    @classmethod
    def of(cls, ev: AttitudeEval) -> FrameAttitude:
        return cls(ev.C_BI, ev.spin_axis_I, ev.omega_B, ev.names, J=ev.J)

    @property
    def J(self) -> np.ndarray:
        """(N, 3, k) ``∂δθ/∂x`` (materialized)."""
        if self._J is None:
            n = self.C_chain.shape[0]
            eye = np.broadcast_to(np.eye(3), (n, 3, 3))
            self._J = self._gyro_chain(eye, self.C_chain, np.arange(len(self.names)))
        return self._J

    def chain(self, D: np.ndarray, sel, out: np.ndarray | None = None, *, w: np.ndarray | None = None) -> np.ndarray:
        """``(w D) @ J[:, :, sel]``, (N, m, len(sel)); ``sel`` ascending positions in ``names``.

        ``out`` (N, m, len(sel)) may be a view into a larger array (written in place).
        ``w`` (N, m) scales the rows (the whitening ``R^-1/2`` of the batch); a row of
        weight zero may come out as zeros or as NaN when ``D`` is NaN there, so a caller
        that weights unused rows zero clears them afterwards.
        """
        sel = np.asarray(sel, dtype=int)
        n, m = D.shape[:2]
        if out is None:
            out = np.empty((n, m, sel.size))
        if self.fill_rows(D, sel, out, w=w):
            return out
        if w is not None:
            D = D * w[:, :, None]
        if self._gyro is None or self._J is not None:
            J = self.J
            if J.ndim == 3 and J.strides[0] == 0:  # one matrix for every frame
                out[...] = (D.reshape(-1, 3) @ J[0][:, sel]).reshape(n, m, -1)
            else:
                o = 0
                for a, b in _runs(sel):
                    np.matmul(D, J[:, :, a:b], out=out[:, :, o : o + b - a])
                    o += b - a
            return out
        return self._gyro_chain(D, D @ self.C_chain, sel, out)

    @property
    def can_fill_rows(self) -> bool:
        """True when :meth:`fill_rows` can run (gyro-carried, factored, numba)."""
        return self._gyro is not None and self._J is None and COMPILED

    def fill_rows(
        self, D: np.ndarray, sel, out: np.ndarray, *, w: np.ndarray | None = None, P: np.ndarray | None = None, pcol=()
    ) -> bool:
        """Whole rows in one compiled pass, when this attitude can (gyro-carried, numba):
        ``(w D) J[:, :, sel]`` into ``out[..., :len(sel)]`` and the prepared columns
        ``P`` (q, N, m) into ``out[..., pcol]`` (added where ``pcol`` < len(sel)); a row of
        weight zero comes out as zeros (:func:`~gcs_core.problem.kernels.chain_rows`),
        except that the ``D W s`` term of frames between knots is added after it.
        Returns False (and writes nothing) when it cannot.
        """
        if not self.can_fill_rows:
            return False
        sel = np.asarray(sel, dtype=int)
        Ma, (E, j), gen = self._gyro
        n, m = D.shape[:2]
        jidx = np.arange(j.start, j.stop, j.step or 1) if isinstance(j, slice) else np.asarray(j)
        rs, ps = sel[sel < 3], sel[sel >= 3] - 3
        if P is None:
            P = np.empty((0, n, m))
        kernels.chain_rows(
            D,
            np.ones((n, m)) if w is None else w,
            self.C_chain,
            E,
            jidx,
            Ma,
            rs,
            ps,
            P,
            np.asarray(pcol, dtype=np.int64),
            out,
        )
        if gen is not None and ps.size:
            g, Wg, sg = gen
            Dg = D[g] if w is None else D[g] * w[g][:, :, None]
            out[g, :, rs.size : rs.size + ps.size] += (Dg @ Wg[:, :, ps]) * sg[:, None, None]
        return True

    def fill_gram(
        self, D: np.ndarray, sel, G: np.ndarray, buf: np.ndarray, *, w: np.ndarray, P: np.ndarray, pcol
    ) -> bool:
        """``G += Σ rowᵀ row`` over the rows :meth:`fill_rows` would write, without writing
        them (:func:`~gcs_core.problem.kernels.chain_gram`; ``G`` (K, K) gets its lower
        triangle, ``buf`` (T, K) is the tile; the ``D W s`` term of frames between knots is
        included). Returns False (and adds nothing) when it cannot: no compiled kernel or
        BLAS pointer.
        """
        if not self.can_fill_rows or kernels.DSYRK is None:
            return False
        sel = np.asarray(sel, dtype=int)
        Ma, (E, j), gen = self._gyro
        rs, ps = sel[sel < 3], sel[sel >= 3] - 3
        n = D.shape[0]
        jidx = np.arange(j.start, j.stop, j.step or 1) if isinstance(j, slice) else np.asarray(j)
        gidx = np.full(n, -1, dtype=np.int64)
        if gen is not None and ps.size:
            g, Wg, sg = gen
            gidx[g] = np.arange(np.count_nonzero(g) if np.asarray(g).dtype == bool else np.asarray(g).size)
            Wg, sg = np.ascontiguousarray(Wg, dtype=float), np.ascontiguousarray(sg, dtype=float)
        else:
            Wg, sg = np.zeros((1, 3, 1)), np.zeros(1)
        kernels.chain_gram(
            D,
            w,
            self.C_chain,
            E,
            jidx,
            Ma,
            rs,
            ps,
            P,
            np.asarray(pcol, dtype=np.int64),
            gidx,
            Wg,
            sg,
            G,
            buf,
            kernels.DSYRK,
        )
        return True

    def _gyro_chain(self, D, DC, sel, out=None):
        """``D J`` with ``J = [C M_a | C X + W s]``: ``DC M_a``, ``DC X`` (+ ``D W s``);
        ``X = E[j]`` is read column run by column run (a view when ``j`` is a slice)."""
        Ma, (E, j), gen = self._gyro
        n, m = DC.shape[:2]
        if out is None:
            out = np.empty((n, m, sel.size))
        rs = sel[sel < 3]
        if rs.size:
            out[:, :, : rs.size] = (DC.reshape(-1, 3) @ Ma[:, rs]).reshape(n, m, -1)
        o = rs.size
        for a, b in _runs(sel[sel >= 3] - 3):
            part = out[:, :, o : o + b - a]
            np.matmul(DC, E[j, :, a:b], out=part)
            if gen is not None:
                g, Wg, sg = gen
                part[g] += (D[g] @ Wg[:, :, a:b]) * sg[:, None, None]
            o += b - a
        return out

    def as_eval(self) -> AttitudeEval:
        return AttitudeEval(self.C_BI, self.spin_axis_I, self.names, self.J, omega_B=self.omega_B)


def _runs(idx) -> list[tuple[int, int]]:
    """Contiguous runs ``[a, b)`` of ascending positions (slices keep matmul operands views)."""
    idx = np.asarray(idx, dtype=int)
    if not idx.size:
        return []
    cut = np.flatnonzero(np.diff(idx) != 1) + 1
    return [(int(r[0]), int(r[-1]) + 1) for r in np.split(idx, cut)]


def _vee(S):
    """Vector of a skew matrix ``[a×]`` (..., 3, 3) -> (..., 3)."""
    return np.stack([S[..., 2, 1], S[..., 0, 2], S[..., 1, 0]], -1)


def rpy_error_jacobian(roll, pitch, yaw) -> np.ndarray:
    """(3, 3) ``∂δθ/∂(φ, θ, ψ)`` for ``C = B(φ, θ, ψ) A`` (Eq 4-22 chained).

    ``δC = Σ ∂B/∂x_i A δx_i = −[δθ×] C`` gives ``[δθ×] = −Σ (∂B/∂x_i) Bᵀ δx_i``.
    """
    B = euler123_to_dcm(roll, pitch, yaw)
    dB = euler123_partials(roll, pitch, yaw)
    return np.stack([_vee(-(dB[i] @ B.T)) for i in range(3)], -1)


def rpy_specs(roll=0.0, pitch=0.0, yaw=0.0, sigma=1.0 * DEG) -> tuple[ParamSpec, ...]:
    return tuple(
        ParamSpec(
            n.split(".")[1],
            "rad",
            float(v),
            sigma,
            seed=True,
            effect="attitude",
            description=f"{n.split('.')[1]} angle, Eq 4-4",
            element=n,
        )
        for n, v in zip(RPY, (roll, pitch, yaw))
    )


@runtime_checkable
class AttitudeProvider(Protocol):
    """What the estimators, the predictor and the diagnosis ask of ``Problem.attitude``.

    Every provider in this package (and the estimators' own: the Kalman filter's
    segment attitude, the whole-span corrected attitude) answers all of it; most take
    the defaults of :class:`ProviderDefaults`.

    Attributes
    ----------
    kind : ``"three_axis"`` (partials with respect to the body error ``δθ``) or
        ``"spinning"`` (with respect to the spin axis ``Â``).
    names : element names of the provider's partials (``AttitudeEval.names``).
    gyro : the name of the gyro carrying the attitude (Eq 4-32, 4-33), None when none does.
    t_ref : epoch of the attitude elements [s], None when they hold at every time.
    ref : the provider whose roll/pitch/yaw the elements are (Eq 4-6): ``reference(t)``
        gives the reference frame ``A(t)``, ``rpy_from_dcm(C, t)`` the elements of an
        attitude ``C``; None when the elements are no roll/pitch/yaw (spinning, error angles).
    """

    kind: str

    @property
    def gyro(self) -> str | None: ...

    @property
    def t_ref(self) -> float | None: ...

    @property
    def names(self) -> tuple[str, ...]: ...

    @property
    def ref(self) -> ReferenceAttitude | ManeuverAttitude | None: ...

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        """Attitude and partials at the times ``t`` (N,)."""

    def frames(self, values: Mapping[str, float], t, *, partials: bool = True) -> FrameAttitude:
        """The same at the frames of one chunk, partials kept factored (:class:`FrameAttitude`)."""

    def covers(self, t) -> np.ndarray:
        """(N,) True where the provider reaches ``t`` (a gyro-carried one: inside the gyro's span)."""

    def block_edges(self) -> np.ndarray:
        """Times where a propagation block ends (a chunk of frames never straddles one); empty
        when the provider has no blocks."""


class ProviderDefaults:
    """The :class:`AttitudeProvider` members of a provider without gyro, blocks or span limits."""

    gyro: str | None = None
    t_ref: float | None = None

    @property
    def ref(self) -> ReferenceAttitude | ManeuverAttitude | None:
        return None

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        raise NotImplementedError

    def frames(self, values: Mapping[str, float], t, *, partials: bool = True) -> FrameAttitude:
        return FrameAttitude.of(self.evaluate(values, t))

    def covers(self, t) -> np.ndarray:
        return np.ones(np.shape(np.asarray(t, dtype=float)), dtype=bool)

    def block_edges(self) -> np.ndarray:
        return np.zeros(0)


class ReferenceAttitude(ProviderDefaults):
    """Constant roll/pitch/yaw relative to the reference frame (Eq 4-6)."""

    kind = "three_axis"

    def __init__(self, mode: str, ephemeris, builder=None):
        self.mode = mode
        self.ephemeris = ephemeris
        self.builder = builder

    @property
    def ref(self) -> ReferenceAttitude:
        """Itself: the elements are roll/pitch/yaw about its reference frame."""
        return self

    @property
    def names(self) -> tuple[str, ...]:
        return RPY

    def reference(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        if self.mode == "inertial":
            return np.broadcast_to(np.eye(3), (t.size, 3, 3))
        r, v = self.ephemeris.state(t)
        return reference_dcm(self.mode, r, v, self.ephemeris.sun_geocentric(t))

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        """``C = B A(t)`` (Eq 4-6) and, for ``earth_pointing``, the body rate
        ``ω_B = B ω_R`` with ``ω_R = (0, −(v·x_R)/|r|, 0)`` the turn of the frame along the
        orbit (Eq 4-34), which a sensor's time-tag offset needs (the body turns by ``ω Δt``,
        1.3° in 20 s in low orbit). The Sun-pointing frame turns at 2e-7 rad/s (0.04 arcsec
        in 1 s) and the inertial one not at all: their ``omega_B`` is None (zero)."""
        rpy = [values[n] for n in RPY]
        B = euler123_to_dcm(*rpy)
        t = np.atleast_1d(np.asarray(t, float))
        omega = None
        if self.mode == "earth_pointing":
            r, v = self.ephemeris.state(t)
            A = reference_dcm(self.mode, r, v)
            omega = earth_pointing_rate(r, v, frame="R") @ B.T  # ω_B = B ω_R
        else:
            A = self.reference(t)
        C = B @ A
        J = np.broadcast_to(rpy_error_jacobian(*rpy), (C.shape[0], 3, 3))
        return AttitudeEval(C, None, RPY, J, omega_B=omega)

    def rpy_from_dcm(self, C, t) -> tuple[float, float, float]:
        A = self.reference(np.atleast_1d(t))[0]
        roll, pitch, yaw = (float(a) for a in dcm_to_euler123(C @ A.T))
        return roll, pitch, yaw


class SpinAttitude(ProviderDefaults):
    """Spin axis by right ascension and declination (Eq 4-2)."""

    kind = "spinning"
    names = RADEC

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        ra, dec = values["att.ra"], values["att.dec"]
        d_ra, d_dec = spin_axis_partials(ra, dec)
        n = np.atleast_1d(np.asarray(t)).size
        J = np.broadcast_to(np.stack([d_ra, d_dec], -1), (n, 3, 2))
        return AttitudeEval(None, spin_axis(ra, dec), RADEC, J)


def rpy_error_jacobians(rpy: np.ndarray) -> np.ndarray:
    """(N, 3, 3) ``∂δθ/∂(φ, θ, ψ)`` at N angle triples (Eq 4-22, vectorized).

    ``[δθ×] = −Σ_i (∂B/∂x_i) Bᵀ δx_i`` for ``C = B(φ, θ, ψ) A``.
    """
    rpy = np.atleast_2d(np.asarray(rpy, dtype=float))
    B = euler123_to_dcm(rpy[:, 0], rpy[:, 1], rpy[:, 2])
    dB = euler123_partials(rpy[:, 0], rpy[:, 1], rpy[:, 2])  # (N, 3, 3, 3)
    BT = np.swapaxes(B, -1, -2)
    return np.stack([_vee(-(dB[:, i] @ BT)) for i in range(3)], -1)


class ManeuverAttitude(ProviderDefaults):
    """Gyro-free three-axis attitude following a known maneuver profile (module docstring)."""

    kind = "three_axis"
    names = RPY

    def __init__(self, reference: ReferenceAttitude, offsets):
        self.reference_attitude = reference
        self.mode = reference.mode
        self.offsets = offsets

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        rpy = np.array([values[n] for n in RPY])[None, :] + self.offsets(t)
        C = euler123_to_dcm(rpy[:, 0], rpy[:, 1], rpy[:, 2]) @ self.reference_attitude.reference(t)
        return AttitudeEval(C, None, RPY, rpy_error_jacobians(rpy))

    @property
    def ref(self) -> ManeuverAttitude:
        """Itself: the elements are the roll/pitch/yaw at ``start``, before the maneuvers."""
        return self

    def reference(self, t) -> np.ndarray:
        """(N, 3, 3) the reference frame ``A(t)`` (Eq 4-6)."""
        return self.reference_attitude.reference(t)

    def rpy_from_dcm(self, C, t) -> tuple[float, float, float]:
        A = self.reference_attitude.reference(np.atleast_1d(t))[0]
        roll, pitch, yaw = np.array(dcm_to_euler123(C @ A.T)) - self.offsets(np.atleast_1d(t))[0]
        return float(roll), float(pitch), float(yaw)


class BodyErrorAttitude(ProviderDefaults):
    """A fixed attitude history whose elements are the body error angles (``J = I``).

    Parameters
    ----------
    base : an attitude provider; ``base_values`` its element values.
    """

    kind = "three_axis"
    names = ERR

    def __init__(self, base, base_values: Mapping[str, float]):
        self.base = base
        self.base_values = dict(base_values)

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        att = self.base.evaluate(self.base_values, t)
        n = att.C_BI.shape[0]
        return AttitudeEval(att.C_BI, None, ERR, np.broadcast_to(np.eye(3), (n, 3, 3)), omega_B=att.omega_B)
