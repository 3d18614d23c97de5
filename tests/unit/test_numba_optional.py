"""numba is optional (the ``fast`` extra): without it the numpy forms give the same fits.

The compiled kernels (``gcs_core/estimators/*/*kernels.py``, the knot accumulation) and their
numpy forms are two codings of the same sums. Here one simulated mission is fitted three
ways (the batch, the whole-span fit with the gyro noise as process noise, the Kalman filter
and smoother, Eq 3-3/3-4) in this process, with the compiled kernels when numba imports,
and in a child process with ``GCS_NO_NUMBA=1`` (the numpy forms); the estimates must agree
to round-off in units of their own σ, and the χ² to round-off.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gcs_core import compiled

ROOT = Path(__file__).resolve().parents[2]

#: the two engines sum the same terms in another order: estimates agree to round-off
round_off_in_sigma = 1e-6
#: relative round-off of σ and χ²
round_off = 1e-8

#: fits one short mission three ways and prints {method: {x, sigma, chi2}} as JSON
FITS = """
import json, sys
import numpy as np
sys.path.insert(0, "tests/statistical")
from gcs_core import compiled
from gcs_core.estimators.batch.least_squares import batch_fit
from gcs_core.estimators.whole_span.fit import whole_span_fit
from gcs_core.estimators.kalman.stepping import Filtr
from test_filter_consistency import sim_problem, simulate

mission, _ = simulate(7, duration_s=600.0)
out = {"compiled": bool(compiled.COMPILED)}
for name, fit in (("batch", lambda p: batch_fit(p)), ("whole_span", lambda p: whole_span_fit(p)),
                  ("kalman", lambda p: Filtr(p, block_seconds=200.0).run())):
    r = fit(sim_problem(mission))
    s = r.sigma
    out[name] = {"names": list(r.solve_for), "x": np.asarray(r.x, float).tolist(),
                 "sigma": [s[n] for n in r.solve_for],
                 "chi2": float(getattr(r, "chi2", np.nan))}
print(json.dumps(out))
"""


def _fits(no_numba: bool) -> dict:
    env = dict(os.environ)
    env.pop("GCS_NO_NUMBA", None)
    if no_numba:
        env["GCS_NO_NUMBA"] = "1"
    done = subprocess.run([sys.executable, "-c", FITS], cwd=ROOT, env=env, check=True, capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not compiled.COMPILED, reason="numba not importable: only the numpy forms run")
def test_numpy_forms_fit_as_the_compiled_kernels():
    fast, plain = _fits(no_numba=False), _fits(no_numba=True)
    assert fast["compiled"] and not plain["compiled"]
    for method in ("batch", "whole_span", "kalman"):
        a, b = fast[method], plain[method]
        assert a["names"] == b["names"], method
        sig = np.asarray(a["sigma"])
        z = (np.asarray(a["x"]) - np.asarray(b["x"])) / sig
        assert np.max(np.abs(z)) < round_off_in_sigma, (method, a["names"][int(np.argmax(np.abs(z)))])
        np.testing.assert_allclose(b["sigma"], sig, rtol=round_off, err_msg=method)
        if np.isfinite(a["chi2"]):
            assert b["chi2"] == pytest.approx(a["chi2"], rel=round_off), method
