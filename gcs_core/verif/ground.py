"""The ground attitude of a fitted analysis, with its 1-σ (for VERIF and the ASF).

The fitted problem's attitude provider gives the attitude at any time it covers and its
partials ``J(t) = ∂δθ(t)/∂x`` with respect to the solve-for elements (attitude angles,
and with a gyro the gyro parameters, Eq 4-37). With ``P`` the fit covariance
(consider contributions included), the body-axis attitude covariance is::

    Σ_B(t) = J(t) P J(t)ᵀ

and about the roll/pitch/yaw axes, with ``J_r`` the Jacobian of Eq 4-22 at the ground
angles, ``Σ_rpy = J_r⁻¹ Σ_B J_r⁻ᵀ``. For a constant roll/pitch/yaw attitude ``J``
involves only ``att.roll/pitch/yaw`` and ``Σ_rpy`` is their fit covariance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_core.errors import EstimationError, InputError
from gcs_core.frames.rotations import dcm_to_euler123, quat_from_dcm, quat_normalize
from gcs_core.problem.attitude import rpy_error_jacobians


@dataclass(frozen=True)
class GroundAttitude:
    """Fitted attitude at N times.

    Attributes
    ----------
    t : (N,) times [s]; q : (N, 4) scalar-last GCI-to-body quaternions (q4 ≥ 0);
    C_BI : (N, 3, 3); sigma_body : (N, 3) 1-σ about body x, y, z [rad];
    sigma_rpy : (N, 3) 1-σ of roll, pitch, yaw [rad]; A : (N, 3, 3) GCI-to-reference.
    """

    t: np.ndarray
    q: np.ndarray
    C_BI: np.ndarray
    sigma_body: np.ndarray
    sigma_rpy: np.ndarray
    A: np.ndarray


def _reference(attitude):
    ref = attitude.ref
    if ref is None:
        raise InputError(
            "attitude verification needs a three-axis mission (a spinning mission has no roll/pitch/yaw)",
            key="mission.attitude_mode",
        )
    return ref


def covered(analysis, t) -> np.ndarray:
    """(N,) True where the fitted attitude provider reaches ``t``."""
    att = analysis.problem.attitude
    t = np.asarray(t, dtype=float)
    return att.covers(t)


def ground_attitude(analysis, t) -> GroundAttitude:
    """The fitted attitude of ``analysis`` at ``t`` (inside its coverage), module docstring."""
    res = analysis.result
    if res is None:
        raise EstimationError("the analysis has not been fitted yet (run the fit first)")
    problem = analysis.problem
    att_provider = problem.attitude
    ref = _reference(att_provider)
    t = np.asarray(t, dtype=float)
    values = res.state.values()
    att = res.attitude_provider(att_provider).evaluate(values, t)
    names = list(res.solve_for)
    col = {nm: j for j, nm in enumerate(names)}
    J = np.zeros((t.size, 3, len(names)))
    for a, nm in enumerate(att.names):
        if nm in col:
            J[:, :, col[nm]] = att.J[:, :, a]
    S_body = np.einsum("nia,ab,njb->nij", J, res.P_consider, J)
    S_body = S_body + res.attitude_wander_covariance(att.C_BI, t, J)  # e.g. the gyro wander of knots
    A = np.asarray(ref.reference(t))
    rpy = np.column_stack(dcm_to_euler123(att.C_BI @ np.swapaxes(A, -1, -2)))
    Jr_inv = np.linalg.solve(rpy_error_jacobians(rpy), np.broadcast_to(np.eye(3), (t.size, 3, 3)))
    S_rpy = Jr_inv @ S_body @ np.swapaxes(Jr_inv, -1, -2)
    diag = lambda S: np.sqrt(np.clip(np.diagonal(S, axis1=1, axis2=2), 0.0, None))
    return GroundAttitude(
        t=t,
        q=quat_normalize(quat_from_dcm(att.C_BI)),
        C_BI=att.C_BI,
        sigma_body=diag(S_body),
        sigma_rpy=diag(S_rpy),
        A=A,
    )
