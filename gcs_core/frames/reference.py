"""Reference frames of the attitude modes and the spin axis (seed §4.1, ICD §2).

The attitude of a three-axis mission is ``C_BI = [B][A]`` (Eq 4-6): ``[A]`` maps GCI to
the reference frame of the attitude mode, its rows being the reference axes expressed in
GCI (Eq 4-7), and ``[B] = T3(yaw) T2(pitch) T1(roll)`` (Eq 4-4) maps the reference frame
to the body. The reference axes (ICD §2, the reading of Eq 4-1 GCS uses):

- ``inertial``: ``A = I``.
- ``earth_pointing``: ``z_R = −r/|r|`` (nadir), ``y_R = −(r × v)/|r × v|`` (negative
  orbit normal), ``x_R = y_R × z_R`` (along-track for a circular orbit).
- ``sun_pointing``: ``x_R = s/|s|`` with ``s`` the *geocentric* Sun position of the
  ephemeris, as ICD §2 states (the spacecraft-to-Sun direction differs by parallax,
  ≤ 10 arcsec in LEO), ``y_R = (z_GCI × x_R)/|z_GCI × x_R|``, ``z_R = x_R × y_R``.

A spinning mission has no reference frame; its attitude is the spin axis
``Â = (cos α cos δ, sin α cos δ, sin δ)`` (Eq 4-2).

All functions are vectorized: vectors (N, 3), matrices (N, 3, 3).

References
----------
Wertz, J. R. (ed.), *Spacecraft Attitude Determination and Control*, Reidel 1978,
§2.2 (celestial coordinates), §12.1 (attitude matrices).
"""

from __future__ import annotations

import numpy as np

from gcs_core.errors import InputError
from gcs_core.frames.rotations import euler123_to_dcm

__all__ = [
    "REFERENCE_MODES",
    "reference_dcm",
    "spin_axis",
    "spin_axis_partials",
    "ra_dec_from_vector",
    "earth_pointing_rate",
    "attitude_from_rpy",
]

#: Attitude modes that have a reference frame (ICD §2, §3).
REFERENCE_MODES = ("inertial", "earth_pointing", "sun_pointing")


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _as_vectors(v, name):
    v = np.asarray(v, dtype=float)
    if v.shape[-1:] != (3,):
        raise ValueError(f"{name} must have shape (N, 3), got {v.shape}")
    return np.atleast_2d(v)


def reference_dcm(mode: str, r_I=None, v_I=None, sun_I=None) -> np.ndarray:
    """Eq 4-7: the GCI-to-reference matrix ``[A]``, rows = reference axes in GCI.

    Parameters
    ----------
    mode : ``"inertial"``, ``"earth_pointing"`` or ``"sun_pointing"``.
    r_I, v_I : (N, 3) spacecraft position [km] and velocity [km/s] (earth_pointing).
    sun_I : (N, 3) geocentric Sun position [km] (sun_pointing).

    Returns
    -------
    (N, 3, 3) rotation matrices (N from whichever vectors are given; 1 for inertial
    without vectors).
    """
    if mode == "inertial":
        n = next((np.atleast_2d(np.asarray(a)).shape[0] for a in (r_I, v_I, sun_I) if a is not None), 1)
        return np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    if mode == "earth_pointing":
        if r_I is None or v_I is None:
            raise ValueError("earth_pointing needs r_I and v_I")
        r, v = _as_vectors(r_I, "r_I"), _as_vectors(v_I, "v_I")
        z = -_unit(r)  # z_R = -r/|r|
        y = -_unit(np.cross(r, v))  # y_R = -(r x v)/|r x v|
        x = np.cross(y, z)  # x_R = y_R x z_R
        return np.stack([x, y, z], axis=-2)
    if mode == "sun_pointing":
        if sun_I is None:
            raise ValueError("sun_pointing needs sun_I")
        s = _as_vectors(sun_I, "sun_I")
        x = _unit(s)  # x_R = s/|s|
        y = _unit(np.cross(np.array([0.0, 0.0, 1.0]), x))  # y_R = z_GCI x x_R / |.|
        z = np.cross(x, y)  # z_R = x_R x y_R
        return np.stack([x, y, z], axis=-2)
    if mode == "spinning":
        raise InputError(
            "a spinning mission has no reference frame: its attitude is the spin axis (use spin_axis)",
            key="mission.attitude_mode",
        )
    raise InputError(
        f"unknown attitude mode '{mode}' (use one of " + ", ".join(REFERENCE_MODES + ("spinning",)) + ")",
        key="mission.attitude_mode",
    )


def spin_axis(ra, dec) -> np.ndarray:
    """Eq 4-2: ``Â = (cos α cos δ, sin α cos δ, sin δ)`` in GCI. ``ra, dec`` [rad] → (..., 3)."""
    ra, dec = np.asarray(ra, dtype=float), np.asarray(dec, dtype=float)
    cd = np.cos(dec)
    return np.stack(np.broadcast_arrays(np.cos(ra) * cd, np.sin(ra) * cd, np.sin(dec)), -1)


def spin_axis_partials(ra, dec) -> tuple[np.ndarray, np.ndarray]:
    """Partials of Eq 4-2: ``∂Â/∂α = (−sin α cos δ, cos α cos δ, 0)``,
    ``∂Â/∂δ = (−cos α sin δ, −sin α sin δ, cos δ)``. Each (..., 3)."""
    ra, dec = np.asarray(ra, dtype=float), np.asarray(dec, dtype=float)
    ca, sa, cd, sd = np.cos(ra), np.sin(ra), np.cos(dec), np.sin(dec)
    d_ra = np.stack(np.broadcast_arrays(-sa * cd, ca * cd, np.zeros_like(sa * cd)), -1)
    d_dec = np.stack(np.broadcast_arrays(-ca * sd, -sa * sd, cd), -1)
    return d_ra, d_dec


def ra_dec_from_vector(v) -> tuple[np.ndarray, np.ndarray]:
    """Right ascension in ``[0, 2π)`` and declination in ``[−π/2, π/2]`` [rad] of vectors (..., 3).

    Inverse of Eq 4-2; uses ``atan2`` for both angles (accurate near the poles).
    """
    v = np.asarray(v, dtype=float)
    ra = np.mod(np.arctan2(v[..., 1], v[..., 0]), 2.0 * np.pi)
    dec = np.arctan2(v[..., 2], np.hypot(v[..., 0], v[..., 1]))
    return ra, dec


def earth_pointing_rate(r_I, v_I, *, frame: str = "I") -> np.ndarray:
    """Eq 4-34: angular velocity of the earth_pointing reference frame relative to GCI.

    ``ω = −((v · x_R)/|r|) y_R``. Since ``v · x_R = |r × v|/|r|`` and ``y_R = −ĥ``, this is
    ``ω = (r × v)/|r|²``, the instantaneous rate of the radius vector (orbit rate ≈ 1.1e-3
    rad/s in LEO). It omits the slow turn of the orbit plane (J2 nodal drift,
    ~1e-7 rad/s).

    Parameters
    ----------
    r_I, v_I : (N, 3) position [km], velocity [km/s] in GCI.
    frame : ``"I"`` for GCI components, ``"R"`` for reference-frame components
        ``(0, −(v·x_R)/|r|, 0)``. For a nominal attitude with constant roll/pitch/yaw
        the body rate is ``ω_B = [B] ω_R``.

    Returns
    -------
    (N, 3) [rad/s].
    """
    r, v = _as_vectors(r_I, "r_I"), _as_vectors(v_I, "v_I")
    A = reference_dcm("earth_pointing", r, v)
    x, y = A[:, 0, :], A[:, 1, :]
    rate = np.sum(v * x, axis=-1) / np.linalg.norm(r, axis=-1)  # (v . x_R)/|r|
    if frame == "I":
        return -rate[:, None] * y
    if frame == "R":
        out = np.zeros_like(r)
        out[:, 1] = -rate
        return out
    raise ValueError(f"frame must be 'I' or 'R', got {frame!r}")


def attitude_from_rpy(mode: str, roll, pitch, yaw, A=None) -> np.ndarray:
    """Eq 4-6: ``C_BI = T3(yaw) T2(pitch) T1(roll) [A]``.

    Parameters
    ----------
    mode : attitude mode; ``"inertial"`` allows ``A=None`` (identity), the others need ``A``
        from :func:`reference_dcm`; ``"spinning"`` is refused.
    roll, pitch, yaw : (N,) or scalar [rad].
    A : (N, 3, 3) or (3, 3) GCI-to-reference matrices.

    Returns
    -------
    (N, 3, 3) GCI-to-body matrices (broadcast shape of the inputs).
    """
    B = euler123_to_dcm(roll, pitch, yaw)
    if A is None:
        if mode != "inertial":
            raise ValueError(f"mode '{mode}' needs the reference matrix A")
        return np.asarray(B)
    if mode not in REFERENCE_MODES:
        reference_dcm(mode)  # raises the same clear message
    return np.asarray(B) @ np.asarray(A, dtype=float)
