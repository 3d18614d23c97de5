"""The batch-means sandwich σ scale (gcs_core/noise/correlation.py) against truth.

On the laboratory mission of ``test_field_gradient`` (exact kinematics, a field gradient):
with white magnetometer noise of the stated σ the scales sit at 1 within their own
scatter; with each noise draw held over :data:`HOLD` samples (errors correlated over
0.2 s, the information a white-noise fit counts :data:`HOLD` times too high) the
magnetometer's elements scale by ``sqrt(HOLD (1 − a) + a)``, ``a`` the a priori's share of
the element's variance: ``sqrt(HOLD)`` for the elements the data set, 1 for
:data:`PRIOR_SET`, and the scaled σ cover the truth where the fit's own do not.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_field_gradient import EFFECTS, GRADIENT, fit, write_mission
from test_ground_mission import B_LAB, MAG_BIAS, Z_MAX

from gcs_core.errors import InputError
from gcs_core.noise.correlation import sigma_scale

HOLD = 10
#: windows of 1 s: 60 over the span, so each scale scatters by about 1/sqrt(2·60) = 9 %;
#: the bounds are ±3.5 of that
BLOCK_S = 1.0
SCALE_SCATTER = 3.5 / np.sqrt(2 * 60)
MAG_ELEMENTS = (
    tuple(f"MAG.bias_{a}" for a in "xyz")
    + tuple(f"field.G_{ab}" for ab in GRADIENT)
    + tuple(f"field.B_{a}" for a in "xyz")
)

#: the field's magnitude and the magnetometer's three scale factors are one direction on
#: this mission: field.B_y's and field.B_z's variance is the scale factors' a priori's
#: (99 %, :func:`prior_share`), which correlated magnetometer noise does not inflate
PRIOR_SET = ("field.B_y", "field.B_z")
DATA_SET = tuple(n for n in MAG_ELEMENTS if n not in PRIOR_SET)


def prior_share(res) -> dict[str, float]:
    """element -> the a priori's share of its variance, ``(P P₀⁻¹ P)_ii / P_ii`` (the a
    priori a pseudo-observation of influence ``P P₀⁻¹``)."""
    P = np.asarray(res.P)
    s0 = np.array([res.state[n].sigma0 for n in res.solve_for])
    info0 = np.where(np.isfinite(s0) & (s0 > 0), 1.0 / np.where(s0 > 0, s0, 1.0) ** 2, 0.0)
    share = np.einsum("ij,j,ji->i", P, info0, P) / np.diag(P)
    return dict(zip(res.solve_for, share.tolist()))


def _truth():
    return {
        **{f"MAG.bias_{a}": MAG_BIAS[i] for i, a in enumerate("xyz")},
        **{f"field.G_{ab}": x for ab, x in GRADIENT.items()},
        **{f"field.B_{a}": B_LAB[i] for i, a in enumerate("xyz")},
    }


@pytest.fixture(scope="module", params=[1, HOLD], ids=["white", "held"])
def fitted(request, tmp_path_factory):
    root = write_mission(tmp_path_factory.mktemp(f"hold{request.param}"), np.random.default_rng(7), hold=request.param)
    a, res = fit(root, EFFECTS + ("MAG.field_gradient",))
    return request.param, a, res


def test_scale_measures_the_correlation(fitted):
    hold, a, res = fitted
    sc = sigma_scale(a.problem, res, block_s=BLOCK_S)
    assert sc.n_blocks == 60
    share = prior_share(res)
    assert min(share[n] for n in PRIOR_SET) > 0.95 and max(share[n] for n in DATA_SET) < 0.3
    for n in MAG_ELEMENTS:
        expected = np.sqrt(hold * (1.0 - share[n]) + share[n])
        assert abs(sc.scale[n] / expected - 1.0) < SCALE_SCATTER, (n, sc.scale[n], expected)


def test_scaled_sigma_cover_the_truth(fitted):
    hold, a, res = fitted
    v = res.state.values()
    honest = sigma_scale(a.problem, res, block_s=BLOCK_S).honest_sigma(res.sigma)
    z = {n: (v[n] - x) / honest[n] for n, x in _truth().items()}
    worst = max(z, key=lambda n: abs(z[n]))
    assert abs(z[worst]) < Z_MAX, (worst, z[worst])
    if hold > 1:  # the fit's own σ, counting every held draw as new, do not
        z_fit = {n: (v[n] - x) / res.sigma[n] for n, x in _truth().items()}
        assert max(abs(x) for x in z_fit.values()) > Z_MAX


def test_bad_windows_are_refused(fitted):
    _, a, res = fitted
    with pytest.raises(InputError, match="windows"):
        sigma_scale(a.problem, res, block_s=10.0)  # 6 windows
    with pytest.raises(InputError, match="positive"):
        sigma_scale(a.problem, res, block_s=0.0)
    with pytest.raises(InputError, match="no residuals"):
        sigma_scale(a.problem, res, ["NOPE"])
