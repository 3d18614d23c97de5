"""The Earth's rotation seen by a gyro on a ground mission (docs/ground.md).

A ground mission's reference frame is the laboratory's, which turns with the Earth at
``ω_E`` (constant in the lab frame: ``[ephemeris] latitude_deg`` or ``earth_rate_rad_s``).
A gyro measures its rate against inertial space (Eq 4-32 with ``ω_B/I``)::

    ω_meas = G M (ω_B/lab + C_B,lab ω_E) + b + noise

so the body's rate against the lab is ``ω_B/lab = ω − C_B,lab ω_E`` with ``ω`` the
corrected rate (Eq 4-32 inverted). The attitude providers carry the inertial attitude
``C_in`` with ``ω`` as without an Earth rate, from the lab attitude at ``t₀`` (the two
frames coincide there), and turn it into the lab's exactly:

    C_B,lab(t) = C_in(t) exp(+[ω_E (t − t₀)×])

since the lab frame turns about the fixed ``ω_E`` by ``C_lab,in(t) = exp(−[ω_E (t − t₀)×])``
(``Ċ_lab,in = −[ω_E×] C_lab,in``); differentiating, ``Ċ_B,lab = −[(ω − C_B,lab ω_E)×] C_B,lab``:
the term is evaluated at the propagated attitude itself, not at an a priori. A body-frame
perturbation ``δθ`` of ``C_in`` moves ``C_B,lab`` by the same ``δθ``, so the attitude partials
are those of ``C_in`` exactly (:attr:`~gcs_core.problem.attitude.FrameAttitude.C_chain`):
nothing is neglected in the Jacobians.
"""

from __future__ import annotations

import numpy as np

from gcs_core.frames.rotations import rotvec_to_dcm

__all__ = ["lab_attitude"]


def lab_attitude(C_in: np.ndarray, omega: np.ndarray | None, t, t0: float, earth_rate: np.ndarray | None):
    """``(C_B,lab, ω_B/lab)`` from the inertially carried ``C_in`` (N, 3, 3) and its corrected
    rates ``omega`` (N, 3) [rad/s] at times ``t`` (N,) [s], the frames coinciding at ``t0``;
    ``earth_rate`` (3,) the Earth's rate in the lab frame [rad/s]. Without one (None) the
    inputs come back unchanged (module docstring)."""
    if earth_rate is None:
        return C_in, omega
    C = C_in @ rotvec_to_dcm(-np.multiply.outer(np.asarray(t, float) - t0, earth_rate))
    return C, None if omega is None else omega - C @ earth_rate
