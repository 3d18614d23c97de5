"""Attitude verification (seed §3.2.2 VERIF, §4.4): onboard against ground attitudes.

"The standard deviation between the two types of attitudes is computed and compared
with the ground attitude determination accuracy as well as the attitude accuracy
requirement. If this standard deviation is higher than both ..., then a flag will be
set to indicate the need of updating the sensor calibration files" (§4.4)::

    σ = [ Σ_i (θ_i − θ_g)² / (N − 1) ]^{1/2}                                   (§4.4)

per axis, ``θ_i`` the i-th onboard roll, pitch or yaw and ``θ_g`` the ground one at the
same time. The sum is *not* mean-removed: a constant offset (a stale calibration) is
exactly what VERIF must see. The flag rule, per axis and then "any axis"::

    flag_axis = (σ > σ_ground) and (σ > requirement)

with ``σ_ground`` the ground attitude determination accuracy of that axis over the
span (the RMS of the ground 1-σ at the compared times). Both comparisons are strict.

Angles (Eq 4-4 to 4-6). With ``A(t)`` the GCI-to-reference matrix and
``C = T3(ψ) T2(θ) T1(φ) A`` each attitude has roll, pitch and yaw about the reference
frame axes:

* ``angles="euler"`` (default): the Eq 4-5 angles of the onboard and of the ground
  attitude, differenced and wrapped into ``(−π, π]``;
* ``angles="body"``: the small-angle error vector of the onboard attitude in the body
  frame, ``C_ob C_gᵀ = exp(−[δθ×])``, ``δθ = (δx, δy, δz)``. For differences of a few
  degrees or less and attitudes near the reference (roll, pitch, yaw near zero) the
  body axes are the reference axes and ``δθ ≈ (δφ, δθ, δψ)``; it has no gimbal lock.
  Away from zero angles the two differ by the Jacobian of Eq 4-22.

The ground attitude is interpolated to the onboard times by spherical linear
interpolation (slerp) between its samples; onboard times outside the ground span are
not compared.

References
----------
Shoemake, K., "Animating rotation with quaternion curves", SIGGRAPH 1985 (slerp).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_core import display
from gcs_core.errors import InputError
from gcs_core.frames.rotations import dcm_to_euler123, dcm_to_rotvec, quat_normalize, quat_to_dcm
from gcs_core.problem.attitude import AttitudeProvider, ReferenceAttitude
from gcs_core.units import DEG

AXES = ("roll", "pitch", "yaw")
ANGLES = ("euler", "body")
#: default trend window [s] (ten minutes)
TREND_WINDOW_S = 600.0


@dataclass(frozen=True)
class VerifResult:
    """Outcome of one verification (module docstring).

    Attributes
    ----------
    t : (N,) compared onboard times [s].
    diff : (N, 3) onboard − ground roll, pitch, yaw (or body error) [rad].
    mean : (3,) mean difference per axis [rad].
    sigma : (3,) §4.4 standard deviation per axis [rad] (NaN when N < 2).
    n : N, the number of onboard attitudes compared.
    ground_accuracy : (3,) ground attitude determination 1-σ per axis [rad].
    requirement : (3,) attitude accuracy requirement per axis [rad].
    flag_axes : (3,) per-axis flag; flag : any axis flagged.
    reason : one line saying why the flag is (not) set.
    angles : ``"euler"`` or ``"body"``.
    trend_t : (K,) window centres [s]; trend_sigma : (K, 3) §4.4 σ per window [rad];
    trend_n : (K,) attitudes per window; trend_flag : (K,) the flag rule per window.
    """

    t: np.ndarray
    diff: np.ndarray
    mean: np.ndarray
    sigma: np.ndarray
    n: int
    ground_accuracy: np.ndarray
    requirement: np.ndarray
    flag_axes: np.ndarray
    flag: bool
    reason: str
    angles: str
    trend_t: np.ndarray
    trend_sigma: np.ndarray
    trend_n: np.ndarray
    trend_flag: np.ndarray

    def summary(self) -> str:
        """A few lines for a terminal: per-axis mean and σ against both thresholds, the flag."""
        u = _shown(self.sigma, self.ground_accuracy, self.requirement)
        q = lambda x: display.quantity(float(x), "rad", shown=u, with_unit=False)
        lines = [
            f"{self.n} onboard attitudes compared ({self.angles} angles); "
            "§4.4 σ = RMS of onboard − ground about zero (N − 1)",
            f"{'axis':6s} {f'mean [{u}]':>14s} {f'§4.4 σ [{u}]':>14s} {f'ground [{u}]':>14s} "
            f"{f'required [{u}]':>16s}  flag",
        ]
        for k, a in enumerate(AXES):
            lines.append(
                f"{a:6s} {q(self.mean[k]):>14s} {q(self.sigma[k]):>14s} "
                f"{q(self.ground_accuracy[k]):>14s} {q(self.requirement[k]):>16s}  "
                f"{'FLAG' if self.flag_axes[k] else '-'}"
            )
        lines.append(("FLAG: " if self.flag else "ok: ") + self.reason)
        return "\n".join(lines)

    def as_report(self) -> dict:
        """JSON-ready summary in degrees."""
        deg = lambda a: [float(x) / DEG for x in a]
        return {
            "n": self.n,
            "angles": self.angles,
            "axes": list(AXES),
            "mean_deg": deg(self.mean),
            "sigma_deg": deg(self.sigma),
            "ground_accuracy_deg": deg(self.ground_accuracy),
            "requirement_deg": deg(self.requirement),
            "flag_axes": [bool(f) for f in self.flag_axes],
            "flag": self.flag,
            "reason": self.reason,
        }


# ----------------------------------------------------------------------------------------
def slerp(t_knots, q_knots, t) -> np.ndarray:
    """Quaternions at ``t`` by spherical linear interpolation between knots.

    Parameters
    ----------
    t_knots : (M,) increasing; q_knots : (M, 4) scalar-last unit quaternions; t : (N,)
    inside ``[t_knots[0], t_knots[-1]]``.

    Returns
    -------
    (N, 4) unit quaternions (q4 ≥ 0).
    """
    tk = np.asarray(t_knots, dtype=float)
    qk = quat_normalize(np.asarray(q_knots, dtype=float))
    t = np.asarray(t, dtype=float)
    if tk.size == 1:
        return np.broadcast_to(qk[0], (t.size, 4)).copy()
    k = np.clip(np.searchsorted(tk, t, side="right") - 1, 0, tk.size - 2)
    u = ((t - tk[k]) / (tk[k + 1] - tk[k]))[:, None]
    q0, q1 = qk[k], qk[k + 1]
    dot = np.sum(q0 * q1, axis=1)
    q1 = np.where(dot[:, None] < 0.0, -q1, q1)  # the short way round
    dot = np.abs(dot)
    omega = np.arccos(np.clip(dot, -1.0, 1.0))[:, None]
    small = omega < 1e-8
    s = np.sin(np.where(small, 1.0, omega))
    w0 = np.where(small, 1.0 - u, np.sin((1.0 - u) * omega) / s)
    w1 = np.where(small, u, np.sin(u * omega) / s)
    return quat_normalize(w0 * q0 + w1 * q1)


def _reference_matrices(reference, mode: str, t: np.ndarray) -> np.ndarray:
    """(N, 3, 3) GCI-to-reference ``A(t)`` from whatever ``reference`` is."""
    if reference is None:
        if mode not in (None, "inertial"):
            raise InputError(
                f"a '{mode}' mission needs its reference frame (an ephemeris)", key="verification.reference"
            )
        return np.broadcast_to(np.eye(3), (t.size, 3, 3))
    if isinstance(reference, AttitudeProvider):
        if reference.ref is None:
            raise InputError(
                "attitude verification needs a three-axis reference (roll/pitch/yaw)", key="verification.reference"
            )
        return np.asarray(reference.ref.reference(t))
    if hasattr(reference, "state") and hasattr(reference, "sun_geocentric"):  # an Ephemeris
        return ReferenceAttitude(mode, reference).reference(t)
    if callable(reference):
        return np.asarray(reference(t))
    A = np.asarray(reference, dtype=float)
    return np.broadcast_to(A, (t.size, 3, 3))


def attitude_differences(q_onboard, q_ground, A, angles: str = "euler") -> np.ndarray:
    """(N, 3) onboard − ground angles (module docstring) for paired quaternions.

    ``A`` (N, 3, 3) is the GCI-to-reference matrix at each time.
    """
    if angles not in ANGLES:
        raise InputError(f"angles must be one of {', '.join(ANGLES)}", key="verification.angles")
    C_ob = quat_to_dcm(quat_normalize(q_onboard))
    C_g = quat_to_dcm(quat_normalize(q_ground))
    if angles == "body":
        return dcm_to_rotvec(C_ob @ np.swapaxes(C_g, -1, -2))
    At = np.swapaxes(A, -1, -2)
    a_ob = np.column_stack(dcm_to_euler123(C_ob @ At))
    a_g = np.column_stack(dcm_to_euler123(C_g @ At))
    return np.mod(a_ob - a_g + np.pi, 2.0 * np.pi) - np.pi


def seed_sigma(diff: np.ndarray) -> np.ndarray:
    """§4.4: ``[Σ (θ_i − θ_g)² / (N − 1)]^{1/2}`` per column (NaN for N < 2). (3,)."""
    n = diff.shape[0]
    if n < 2:
        return np.full(diff.shape[1], np.nan)
    return np.sqrt(np.sum(diff**2, axis=0) / (n - 1))


def flag_rule(sigma, ground_accuracy, requirement) -> np.ndarray:
    """§4.4 per axis: ``σ > σ_ground`` and ``σ > requirement`` (strict; NaN never flags)."""
    sigma = np.asarray(sigma, dtype=float)
    with np.errstate(invalid="ignore"):
        return (sigma > np.asarray(ground_accuracy, float)) & (sigma > np.asarray(requirement, float))


def _reason(sigma, ground, req, flags, n) -> str:
    if n < 2:
        return f"{n} onboard attitude(s) overlap the ground attitude: at least 2 are needed"
    parts = []
    u = _shown(sigma, ground, req)
    q = lambda x: display.quantity(float(x), "rad", shown=u)
    for a, s, g, r, f in zip(AXES, sigma, ground, req, flags):
        if f:
            parts.append(f"{a}: σ = {q(s)} exceeds both the ground accuracy {q(g)} and the requirement {q(r)}")
    if parts:
        return "; ".join(parts) + " — the onboard sensor calibration needs an update"
    worst = int(np.nanargmax(sigma / np.maximum(np.maximum(ground, req), 1e-300)))
    return (
        f"no axis exceeds both thresholds (largest: {AXES[worst]} σ = {q(sigma[worst])} "
        f"vs ground {q(ground[worst])}, requirement {q(req[worst])})"
    )


def _shown(*arrays) -> str:
    """One display unit for a verification's angles, chosen from the largest σ or threshold."""
    return display.common_unit("rad", *arrays)


def verify(
    onboard_t,
    onboard_q,
    ground_t,
    ground_q,
    ground_sigma_rad,
    *,
    requirement_rad,
    mode: str = "inertial",
    reference=None,
    angles: str = "euler",
    window_s: float = TREND_WINDOW_S,
) -> VerifResult:
    """Compare onboard attitudes with the ground attitude (§4.4, module docstring).

    Parameters
    ----------
    onboard_t : (N,) onboard times [s]; onboard_q : (N, 4) scalar-last GCI-to-body.
    ground_t : (M,) increasing; ground_q : (M, 4).
    ground_sigma_rad : (M, 3) or (3,) ground 1-σ per axis [rad], in the axes of ``angles``.
    requirement_rad : attitude accuracy requirement [rad], scalar or (3,).
    mode : mission attitude mode (the reference frame of roll, pitch, yaw).
    reference : the reference frame: None (inertial), an
        :class:`~gcs_core.ephem.ephemeris.Ephemeris`, an attitude provider with
        ``reference(t)``, a callable ``t -> A (N, 3, 3)`` or a fixed (3, 3) matrix.
    angles : ``"euler"`` (Eq 4-5 differences) or ``"body"`` (small-angle error vector).
    window_s : trend window length [s] (consecutive, non-overlapping windows from the
        first compared time; the last time belongs to the last window).

    Returns
    -------
    :class:`VerifResult`.
    """
    t_ob = np.asarray(onboard_t, dtype=float).reshape(-1)
    q_ob = np.asarray(onboard_q, dtype=float).reshape(-1, 4)
    t_g = np.asarray(ground_t, dtype=float).reshape(-1)
    q_g = np.asarray(ground_q, dtype=float).reshape(-1, 4)
    if q_ob.shape[0] != t_ob.size or q_g.shape[0] != t_g.size:
        raise InputError("each time needs one quaternion (q1, q2, q3, q4)", key="verification")
    if t_g.size == 0:
        raise InputError("no ground attitude to compare with", key="verification")
    if np.any(np.diff(t_g) <= 0):
        raise InputError("ground attitude times must be strictly increasing", key="verification")
    sig_g = np.asarray(ground_sigma_rad, dtype=float)
    sig_g = np.broadcast_to(sig_g, (t_g.size, 3)) if sig_g.shape in ((3,), (1, 3)) else sig_g
    if sig_g.shape != (t_g.size, 3):
        raise InputError(
            f"ground_sigma_rad must have shape ({t_g.size}, 3) or (3,), not {sig_g.shape}", key="verification"
        )
    req = np.broadcast_to(np.asarray(requirement_rad, dtype=float), (3,)).copy()

    inside = (t_ob >= t_g[0]) & (t_ob <= t_g[-1])
    t = t_ob[inside]
    q_ground = slerp(t_g, q_g, t)
    diff = (
        attitude_differences(q_ob[inside], q_ground, _reference_matrices(reference, mode, t), angles)
        if t.size
        else np.zeros((0, 3))
    )
    sg = np.column_stack([np.interp(t, t_g, sig_g[:, a]) for a in range(3)]) if t.size else np.zeros((0, 3))
    n = int(t.size)
    sigma = seed_sigma(diff)
    ground = np.sqrt(np.mean(sg**2, axis=0)) if n else np.full(3, np.nan)
    flags = flag_rule(sigma, ground, req)
    mean = diff.mean(axis=0) if n else np.full(3, np.nan)

    # trend: the same statistic and rule in consecutive windows
    if n and window_s > 0:
        K = max(int(np.ceil((t[-1] - t[0]) / window_s - 1e-9)), 1)
        k = np.clip(((t - t[0]) // window_s).astype(int), 0, K - 1)  # the last time closes the last window
        tr_t = t[0] + (np.arange(K) + 0.5) * window_s
        tr_s = np.full((K, 3), np.nan)
        tr_n = np.zeros(K, dtype=int)
        tr_f = np.zeros(K, dtype=bool)
        for j in range(K):
            sel = k == j
            tr_n[j] = int(sel.sum())
            tr_s[j] = seed_sigma(diff[sel])
            g = np.sqrt(np.mean(sg[sel] ** 2, axis=0)) if tr_n[j] else np.full(3, np.nan)
            tr_f[j] = bool(np.any(flag_rule(tr_s[j], g, req)))
    else:
        tr_t, tr_s, tr_n, tr_f = np.zeros(0), np.zeros((0, 3)), np.zeros(0, int), np.zeros(0, bool)
    return VerifResult(
        t=t,
        diff=diff,
        mean=mean,
        sigma=sigma,
        n=n,
        ground_accuracy=ground,
        requirement=req,
        flag_axes=flags,
        flag=bool(np.any(flags)),
        reason=_reason(sigma, ground, req, flags, n),
        angles=angles,
        trend_t=tr_t,
        trend_sigma=tr_s,
        trend_n=tr_n,
        trend_flag=tr_f,
    )
