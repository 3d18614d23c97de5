"""Whole-span partials stay exact when the knot corrections are large (days to a week).

Over a week the gyro-carried attitude of the batch wanders by degrees from the truth, so
the whole-span fit starts with knot corrections of that size. Its Gauss–Newton direction
is only as good as its partials there; checked against central differences of χ² at
corrections of 0.1 rad (5.7°):

* the knot columns chain through the left Jacobian of the exp map
  (:func:`gcs_core.estimators.whole_span.knots.chained_attitude`), not the corrected attitude alone
  (off by |α|/2);
* the statics' columns are the gyro-carried attitude's (``FrameAttitude.C_chain``): a
  body-frame perturbation of ``C_gyro`` moves ``C = C_gyro exp(−[α×])`` by the same
  rotation (taken at the corrected attitude, the yaw column was 2.4× off);
* the knots' drift-bias axes are held through a fit, so the cost depends on ``(x, z)``
  alone (``Passes.R_fixed``).

Forty minutes of the Sun-pointing scenario with its flight-typical IRU, seed 7; the
corrections are a seeded random walk scaled to 0.1 rad.
"""

from __future__ import annotations

import numpy as np
import pytest

from gcs_core.estimators.batch.least_squares import BatchOptions, batch_fit
from gcs_core.estimators.whole_span import fit as sb
from gcs_core.estimators.whole_span import passes as wsp
from gcs_core.io.importer import load_mission
from gcs_core.problem.build import build_problem
from gcs_core.sim.scenarios import nominal_threeaxis
from gcs_core.sim.writer import write_mission

#: central differences of χ² against the analytic gradient (second-order terms of a
#: step of 1e-3 σ, and the gyro propagation's own first-order partials)
gradient_agreement = 5e-3
large_correction_rad = 0.1


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    cfg = nominal_threeaxis("sun_pointing", seed=7, duration_s=2400.0)
    problem = build_problem(load_mission(write_mission(cfg, tmp_path_factory.mktemp("large") / "m")))
    b = batch_fit(problem, BatchOptions(edit_k=None, max_iterations=3))
    names = tuple(b.solve_for)
    grid = sb.make_knots(problem, sb.process_noise(problem), b.information, names)
    passes = wsp.Passes(problem, names, grid, np.array(b.x), np.zeros(len(names)))
    passes.stream = False  # keep the knot rows for the check
    rng = np.random.default_rng(11)
    z = np.zeros((grid.K, grid.d))
    z[1:, :3] = np.cumsum(rng.standard_normal((grid.K - 1, 3)), 0)
    z[:, :3] *= large_correction_rad / np.abs(z[:, :3]).max()
    z[1:, 3:] = rng.standard_normal((grid.K - 1, grid.d - 3)) * 1e-6
    edits = {nm: r.edited for nm, r in b.residuals.items()}
    return passes, np.array(b.x), np.sqrt(np.diag(b.P)), z, edits, rng


def _chi2_slope(passes, x, z, edits, dx, dz):
    up = passes.run(x + dx, z + dz, edits, jacobian=False).chi2
    down = passes.run(x - dx, z - dz, edits, jacobian=False).chi2
    return (up - down) / 2.0


def test_partials_match_differences_at_large_corrections(setup):
    passes, x, sig, z, edits, rng = setup
    lin = passes.run(x, z, edits)
    b, sysk = lin.b, lin.system
    g_knots = sysk.Bk[:, :, -1].copy()  # Σ uᵀ r/σ per knot = −½ ∂χ²/∂z
    zero_x, zero_z = np.zeros_like(x), np.zeros_like(z)
    for part in (slice(0, 3), slice(3, z.shape[1])):
        dz = zero_z.copy()
        dz[1:, part] = rng.standard_normal((z.shape[0] - 1, part.stop - part.start)) * (
            1e-7 if part.start == 0 else 1e-10
        )
        fd = _chi2_slope(passes, x, z, edits, zero_x, dz)
        assert fd == pytest.approx(-2.0 * float(np.sum(g_knots * dz)), rel=gradient_agreement)
    for j, name in enumerate(passes.names):
        if not name.startswith(("att.", "IRU.")):
            continue
        dx = zero_x.copy()
        dx[j] = 1e-3 * sig[j]
        fd = _chi2_slope(passes, x, z, edits, dx, zero_z)
        assert fd == pytest.approx(-2.0 * float(b @ dx), rel=gradient_agreement, abs=1e-3), name
