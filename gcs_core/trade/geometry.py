"""Geometry of a plan that explains its accuracy: how much the geomagnetic field turns.

Seed §2.1.2: a constant magnetometer bias ``b`` changes the measured field magnitude by
``b·B̂``, so the bias is determined along the directions ``B̂`` visits; "the more variation
of B̂, the better for determining b", and the best data pass is where the field direction
varies most (Figure 2-1). :func:`field_turn_deg` measures that variation over a pass.
"""

from __future__ import annotations

import numpy as np


def field_turn_deg(
    orbit, epoch, t0: float, t1: float, *, step: float = 30.0, gaps: tuple[tuple[float, float], ...] = ()
) -> float:
    """Angle [deg] the inertial field direction ``B̂_I`` turns through over ``[t0, t1]``
    outside ``gaps``: the sum of the angles between successive samples ``step`` apart.

    ``orbit`` is a :class:`~gcs_core.ephem.orbit.KeplerOrbit`; the field is IGRF
    (:class:`~gcs_core.ephem.geomag.GeomagField`).
    """
    from gcs_core.ephem.geomag import GeomagField
    from gcs_core.ephem.orbit import build_ephemeris

    eph = build_ephemeris(orbit, epoch, t0, t1, step)
    t = eph.t
    r, _ = eph.state(t)
    B = GeomagField(epoch).field_I(t, r)
    u = B / np.linalg.norm(B, axis=1, keepdims=True)
    keep = np.ones(t.size, bool)
    for a, b in gaps:
        keep &= ~((t > a) & (t < b))
    ang = np.arccos(np.clip(np.einsum("ij,ij->i", u[:-1], u[1:]), -1.0, 1.0))
    inside = keep[:-1] & keep[1:]
    return float(np.degrees(np.sum(ang[inside])))
