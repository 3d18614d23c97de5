"""The gyro's bias following an aux channel inside the gyro-carried attitude (issue 26):
the partials of the attitude with respect to ``bias_<ax>_vs_<channel>`` agree with finite
differences of the propagation, with numba and without, across blocks and between knots."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_core.problem import gyro_attitude
from gcs_core.problem.gyro_attitude import GyroAttitude
from gcs_core.units import DEG

#: a finite difference of the propagated attitude against its partial. The cumulative sums
#: take each row's rate perturbation at the end of its interval, first order in the turn
#: within one row (|ω| Δ ≈ 1e-4 rad here), as every gyro column does (the bias's own
#: column agrees to the same level); 3e-4 of the largest partial holds that with margin
relative_agreement = 3e-4
ONE_DEG_PER_HOUR = DEG / 3600.0


def _heater(t: np.ndarray) -> np.ndarray:
    """A duty cycle: on for 7 s of every 19 s, irregularly phased."""
    return ((np.floor(t) % 19) < 7).astype(float)


def _attitude() -> tuple[GyroAttitude, dict[str, float]]:
    rng = np.random.default_rng(26)
    t = np.arange(1.0, 201.0)
    rates = np.array([5e-5, -1e-4, 3e-5]) + 2e-5 * rng.standard_normal((t.size, 3))
    att = GyroAttitude("inertial", None, "IRU", t, rates, block_knots=64, steps={"iru_heater": _heater(t - 0.5)})
    values = {n: 0.0 for n in att.names}
    values.update({"att.roll": 10 * DEG, "att.pitch": -5 * DEG, "att.yaw": 30 * DEG})  # a slow turn
    values.update({"IRU.G_12": 2e-4, "IRU.align_2": 1e-3, "IRU.bias_x": 1e-6})
    values.update(
        {
            "IRU.bias_x_vs_iru_heater": 0.03 * ONE_DEG_PER_HOUR,
            "IRU.bias_y_vs_iru_heater": -0.02 * ONE_DEG_PER_HOUR,
            "IRU.bias_z_vs_iru_heater": 0.04 * ONE_DEG_PER_HOUR,
        }
    )
    return att, values


def _dtheta(C_new: np.ndarray, C_old: np.ndarray) -> np.ndarray:
    """``δθ`` with ``C_new = exp(−[δθ×]) C_old`` to first order."""
    S = C_new @ np.swapaxes(C_old, 1, 2)
    A = 0.5 * (S - np.swapaxes(S, 1, 2))
    return -np.stack([A[:, 2, 1], A[:, 0, 2], A[:, 1, 0]], -1)


@pytest.mark.parametrize("compiled", [True, False])
def test_step_partials_match_finite_differences(monkeypatch, compiled):
    if compiled and not gyro_attitude.COMPILED:
        pytest.skip("numba not installed")
    monkeypatch.setattr(gyro_attitude, "COMPILED", compiled)
    att, values = _attitude()
    t = np.concatenate([np.arange(3.0, 200.0, 7.0), np.arange(2.5, 199.0, 11.0)])  # on knots and between
    t.sort()
    ev = att.evaluate(values, t)
    C0 = np.array(ev.C_BI)
    h = 1e-9
    for name in ("IRU.bias_x_vs_iru_heater", "IRU.bias_y_vs_iru_heater", "IRU.bias_z_vs_iru_heater", "IRU.bias_x"):
        col = ev.names.index(name)
        plus = dict(values, **{name: values[name] + h})
        minus = dict(values, **{name: values[name] - h})
        fd = (
            _dtheta(np.array(att.evaluate(plus, t).C_BI), C0) - _dtheta(np.array(att.evaluate(minus, t).C_BI), C0)
        ) / (2 * h)
        J = ev.J[:, :, col]
        scale = np.max(np.abs(fd))
        assert scale > 0
        assert np.max(np.abs(J - fd)) < relative_agreement * scale, name


def test_without_steps_the_attitude_is_unchanged():
    """A channel the bias does not follow (k = 0) leaves the attitude and the other partials as they were."""
    att, values = _attitude()
    plain = GyroAttitude("inertial", None, "IRU", att.knots[1:], att.y, block_knots=64)
    t = np.arange(2.5, 199.0, 5.0)
    v0 = {**values, **{f"IRU.bias_{a}_vs_iru_heater": 0.0 for a in "xyz"}}
    a, b = att.evaluate(v0, t), plain.evaluate({n: v0[n] for n in plain.names}, t)
    assert np.max(np.abs(np.array(a.C_BI) - np.array(b.C_BI))) < 1e-14
    assert np.max(np.abs(a.J[:, :, : len(plain.names)] - b.J)) < 1e-12
