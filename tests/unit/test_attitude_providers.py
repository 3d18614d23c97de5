"""Every attitude provider answers the one :class:`AttitudeProvider` protocol
(gcs_core.problem.attitude), and its members say the same thing as its attitude."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_core.models.gyro import G_NAMES
from gcs_core.problem.attitude import (
    RADEC,
    RPY,
    AttitudeProvider,
    BodyErrorAttitude,
    ManeuverAttitude,
    ReferenceAttitude,
    SpinAttitude,
)
from gcs_core.problem.gyro_attitude import GyroAttitude
from gcs_core.units import DEG

#: two evaluations of one attitude agree to round-off
same_rotation = 1e-12
RATE = np.array([1e-3, -2e-3, 5e-4])  # rad/s, a slow turn


def _gyro() -> GyroAttitude:
    t = np.arange(1.0, 201.0)
    return GyroAttitude("inertial", None, "IRU", t, np.tile(RATE, (t.size, 1)), block_knots=64)


def _values(att) -> dict[str, float]:
    values = {n: 0.0 for n in att.names}
    values.update(
        {"att.roll": 10 * DEG, "att.pitch": -5 * DEG, "att.yaw": 30 * DEG, "att.ra": 40 * DEG, "att.dec": 20 * DEG}
    )
    for name in G_NAMES:
        if name in ("G_11", "G_22", "G_33"):
            values[f"IRU.{name}"] = 1.0
    return {n: values[n] for n in att.names}


PROVIDERS = {
    "reference": lambda: ReferenceAttitude("inertial", None),
    "spin": SpinAttitude,
    "maneuver": lambda: ManeuverAttitude(
        ReferenceAttitude("inertial", None), lambda t: np.outer(np.atleast_1d(t), [0.0, 0.0, 1e-3])
    ),
    "body error": lambda: BodyErrorAttitude(ReferenceAttitude("inertial", None), {n: 0.1 for n in RPY}),
    "gyro": _gyro,
}


@pytest.mark.parametrize("kind", sorted(PROVIDERS))
def test_every_provider_answers_the_protocol(kind):
    att = PROVIDERS[kind]()
    assert isinstance(att, AttitudeProvider)
    t = np.linspace(10.0, 150.0, 7)
    values = _values(att)
    ev, fr = att.evaluate(values, t), att.frames(values, t)
    assert ev.names == fr.names == tuple(att.names)
    if att.kind == "three_axis":
        assert np.max(np.abs(ev.C_BI - fr.C_BI)) < same_rotation
        assert np.max(np.abs(ev.J - fr.J)) < same_rotation
    else:
        assert att.names == RADEC and fr.spin_axis_I.shape == (3,)
    assert att.covers(t).all()
    assert att.block_edges().ndim == 1


def test_what_the_members_say():
    ref = ReferenceAttitude("inertial", None)
    assert ref.ref is ref and ref.gyro is None and ref.t_ref is None and ref.block_edges().size == 0
    assert SpinAttitude().ref is None
    gyro = _gyro()
    assert gyro.gyro == "IRU" and gyro.t_ref == gyro.knots[0]
    assert isinstance(gyro.ref, ReferenceAttitude)
    # the gyro's span is what it covers; its blocks end on knots
    assert gyro.covers(np.array([gyro.knots[0] - 1.0, 50.0, gyro.knots[-1] + 1.0])).tolist() == [False, True, False]
    assert np.all(np.isin(gyro.block_edges(), gyro.knots)) and gyro.block_edges().size == 3
    # ref.rpy_from_dcm inverts the reference attitude (Eq 4-6)
    values = _values(ref)
    C = ref.evaluate(values, np.array([0.0])).C_BI[0]
    assert np.allclose(ref.ref.rpy_from_dcm(C, 0.0), [values[n] for n in RPY], atol=same_rotation)
