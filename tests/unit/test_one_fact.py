"""Facts with one definition: the places that use them agree.

* The gyro noise of the data book (σ_v ``arw``, σ_u ``rrw``, σ_e ``electronic``) and
  Farrenkopf's Q (Eq 3-4): the covariance-only predictor and the Kalman filter read the
  same :class:`~gcs_core.models.gyro_noise.GyroNoise` and build their Q with the same
  maps through :func:`~gcs_core.models.gyro_noise.farrenkopf_q`, and so do the whole-span
  knots (GCI-frame maps).
* The read-out noise σ_e, carried by the filter and the predictor as a white attitude
  error of the measurements: truth recovered in σ on seeded in-memory missions (the
  simulator of ``test_filter_consistency``, exact: ``y += (e_k − e_{k−1})/Δt``), and the
  predicted σ matches the filter's.
"""

from __future__ import annotations

import numpy as np
import pytest
from repo_paths import ROOT
from test_filter_consistency import chi2_band, sim_problem, simulate, smoothed_error

from gcs_core.errors import InputError
from gcs_core.estimators.kalman import mekf
from gcs_core.estimators.kalman.options import FilterOptions
from gcs_core.estimators.kalman.stepping import Filtr
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.frames.rotations import rotvec_to_dcm
from gcs_core.io.types import SensorSpec
from gcs_core.models import make_model
from gcs_core.models.gyro_noise import GyroNoise, farrenkopf_q, gyro_noise
from gcs_core.predictor import kalman as pk
from gcs_core.predictor.predict import predict

#: round-off of two evaluations of the same expression
ROUND_OFF = 1e-12
#: tracker noise of the simulated missions [rad] (test_filter_consistency default)
TRACKER_NOISE = 2e-5


def _gyro(**book) -> SensorSpec:
    noise = book.pop("noise", None)
    return SensorSpec("IRU", "gyro", None, (0.0, 0.0, 0.0), noise, {"bias": (0.0, 0.0, 0.0)} | book)


def test_gyro_noise_rule_for_missing_keys():
    """``arw`` absent: σ_v = noise·sqrt(Δt); both absent: InputError naming the key;
    ``rrw`` and ``electronic`` default to 0. The observation model's rate σ uses it."""
    assert gyro_noise(_gyro(arw=3e-7, rrw=3e-10, electronic=2e-6)) == GyroNoise(3e-7, 3e-10, 2e-6)
    assert gyro_noise(_gyro(arw=3e-7)) == GyroNoise(3e-7, 0.0, 0.0)
    assert gyro_noise(_gyro(noise=1e-6), dt=4.0) == GyroNoise(2e-6, 0.0, 0.0)
    with pytest.raises(InputError, match="needs 'arw'"):
        gyro_noise(_gyro())
    dt = 0.25
    g = GyroNoise(3e-7, 3e-10, 2e-6)
    expected = np.sqrt(g.sigma_v**2 / dt + 2 * g.sigma_e**2 / dt**2 + g.sigma_u**2 * dt / 3)
    sigma = make_model(_gyro(arw=3e-7, rrw=3e-10, electronic=2e-6)).sigma(dt)
    np.testing.assert_allclose(sigma, expected, rtol=ROUND_OFF)


def test_predictor_and_filter_share_gyro_noise_and_q(monkeypatch):
    """The predictor's covariance recursion calls the one Q with the filter's noise, maps
    and random-walking bias axes (the filter's own ``gyro_rates`` and ``make_layout``)."""
    mission, _ = simulate(3, duration_s=120.0, electronic=5e-6, arw=3e-6, rrw=3e-9)
    problem = sim_problem(mission)
    calls = []

    def spy(dt, noise, Wy, Wb, axes=()):
        calls.append((noise, np.array(Wy), np.array(Wb), list(axes)))
        return farrenkopf_q(dt, noise, Wy, Wb, axes)

    monkeypatch.setattr(pk, "farrenkopf_q", spy)
    predict(problem, method="kalman")
    assert calls, "the predictor did not call farrenkopf_q"
    noise, Wy, Wb, axes = calls[-1]
    calls.clear()
    monkeypatch.setattr(mekf, "farrenkopf_q", spy)
    filt = Filtr(problem, options=FilterOptions(max_passes=1))
    filt.run()
    assert calls, "the filter did not call farrenkopf_q"
    f_noise, f_Wy, f_Wb, f_axes = calls[-1]  # at the filter's estimate, not the nominal
    assert f_noise == noise and f_axes == axes
    np.testing.assert_allclose(f_Wb, Wb, atol=ROUND_OFF)
    np.testing.assert_allclose(f_Wy, Wy, atol=1e-2)  # G estimated: ΔG ~ 1e-3
    assert noise == filt._noise == mekf.attitude_gyro_noise(problem) == GyroNoise(3e-6, 3e-9, 5e-6)
    values = problem.state.values()
    _, _, Wy_f, Wb_f = mekf.gyro_rates(problem.attitude, values, 0, 1)
    np.testing.assert_allclose(Wy, Wy_f, atol=ROUND_OFF)
    np.testing.assert_allclose(Wb, Wb_f, atol=ROUND_OFF)
    layout = mekf.make_layout(problem, filt._noise)
    assert [f"IRU.bias_{'xyz'[a]}" for a in axes] == list(layout.elements[3 : 3 + layout.nb])


def test_knots_use_farrenkopf_q():
    """The whole-span knots' Q⁻¹ is the inverse of the one Q with the GCI-frame maps."""
    rng = np.random.default_rng(5)
    for sv, su in ((3e-7, 3e-10), (3e-7, 0.0)):
        grid = kn.make_grid(0.0, 3600.0, 60.0, sv, su)
        R = rotvec_to_dcm(rng.normal(size=(grid.K - 1, 3)))
        _, W = kn.transitions(grid, R)
        d = grid.d
        Q = farrenkopf_q(
            np.diff(grid.tau), GyroNoise(sv, su), np.eye(3), -R if d == 6 else np.eye(3), range(3) if d == 6 else ()
        )
        np.testing.assert_allclose(W @ Q, np.broadcast_to(np.eye(d), Q.shape), atol=1e-9)


def test_truth_recovered_with_read_out_noise():
    """σ_e as large as the tracker noise (the tracker residual σ doubles in variance):
    the smoothed state's errors are N(0, P) over seeded runs — NEES in its 95 % χ² band,
    every element within 4σ — and the predictor's final attitude σ is the filter's
    within 2 % (0.3 % on this seed), while without σ_e it is ~18 % smaller.

    The attitude elements are the gyro-carried attitude, which the read-out noise does
    not reach (it telescopes); the true attitude at ``t_ref`` differs from it by that
    instant's read-out error, so its covariance against truth is ``P + σ_e² I``
    (without it the NEES of these seeds is 97 on 57 dof; with it 64)."""
    nees, n = 0.0, 0
    for seed in range(3):
        mission, truth = simulate(40 + seed, duration_s=900.0, electronic=TRACKER_NOISE)
        problem = sim_problem(mission)
        res = Filtr(problem, options=FilterOptions(max_passes=2)).run()
        e = smoothed_error(res, truth)
        P = res.P + np.diag([TRACKER_NOISE**2 if nm.startswith("att.") else 0.0 for nm in res.solve_for])
        z = e / np.sqrt(np.diag(P))
        assert np.all(np.abs(z) < 4.0), dict(zip(res.solve_for, np.round(z, 2)))
        nees += float(e @ np.linalg.solve(P, e))
        n += e.size
    lo, hi = chi2_band(n)
    assert lo < nees < hi, f"NEES {nees:.1f} outside [{lo:.1f}, {hi:.1f}] ({n} dof)"

    f = Filtr(problem, options=FilterOptions(max_passes=1))
    f.run()
    sig_f = np.sqrt(np.diag(f.covariance)[:3])
    pred = predict(problem, method="kalman")
    np.testing.assert_allclose(pred.attitude_sigma[-1], sig_f, rtol=0.02)
    mission0, _ = simulate(42, duration_s=900.0, electronic=0.0)
    pred0 = predict(sim_problem(mission0), method="kalman")
    assert np.all(pred0.attitude_sigma[-1] < 0.85 * pred.attitude_sigma[-1])


def test_physics_defaults_are_one_table():
    """The config's physics defaults, its known keys, the catalogue's "on" values and the
    problem's options are the table of PhysicsOptions."""
    from gcs_core import config
    from gcs_core.problem.prepare import PHYSICS_EFFECTS, PhysicsOptions

    table = PhysicsOptions().as_dict()
    assert config.AnalysisConfig().physics == PhysicsOptions()
    assert config.TABLES["physics"] == tuple(table)
    assert {k: on for k, (on, _) in PHYSICS_EFFECTS.items()} == table
    assert (
        config.parse_toml("[analysis]\nmission = '.'\n")
        and config.config_from_dict({"analysis": {"mission": "."}, "physics": {}}).physics == PhysicsOptions()
    )


def test_config_and_mission_word_bad_values_alike(tmp_path):
    """One wording of TOML value complaints and syntax errors for the analysis config and
    mission.toml (gcs_core.toml_values)."""
    from gcs_core import config
    from gcs_core.errors import ConfigError
    from gcs_core.io.mission import read_mission_spec

    root = ROOT / "sample_data" / "missions" / "hidden-tam-contamination"
    sample = (root / "mission.toml").read_text()

    def mission_error(text):
        d = tmp_path / f"m{len(list(tmp_path.iterdir()))}"
        for f in root.rglob("*.csv"):  # the files it names (mission.toml is read first)
            (d / f.relative_to(root)).parent.mkdir(parents=True, exist_ok=True)
            (d / f.relative_to(root)).touch()
        (d / "mission.toml").write_text(text)
        with pytest.raises(InputError) as err:
            read_mission_spec(d)
        return err.value

    def config_error(text):
        with pytest.raises(ConfigError) as err:
            config.config_from_dict(config.parse_toml(text))
        return err.value

    long_text = "x" * 80
    m = mission_error(sample.replace("noise = 25.0", f'noise = "{long_text}"', 1))
    c = config_error(f'[analysis]\nmission = "."\n[diagnosis]\nsignificance = "{long_text}"\n')
    assert m.message == c.message == f"must be a number, not '{long_text[:36]}..."
    m = mission_error("[mission\nname = 1\n")
    c = config_error("[analysis\nmission = 1\n")
    assert m.message == c.message and m.message.startswith("TOML syntax error") and m.line == c.line == 1


def test_robust_scale_is_the_noise_estimators():
    """The batch's editing and the noise estimator use one MAD-to-σ constant."""
    import inspect

    from gcs_core.estimators.batch import editing as batch
    from gcs_core.noise import measured as noise

    assert batch.MAD_TO_SIGMA is noise.MAD_TO_SIGMA
    assert "1.4826 *" not in inspect.getsource(batch)


def test_one_atomic_write_helper():
    """Only gcs_core/fileperm.py renames temporaries over files or fsyncs (the simulator
    keeps its own on purpose: it imports nothing of the engine)."""
    import re

    root = ROOT
    pattern = re.compile(r"os\.replace\(|mkstemp\(|mkdtemp\(|os\.fsync\(|\.rename\(")
    allowed = {"gcs_core/fileperm.py", "gcs_core/sim/writer.py"}
    offenders = [
        str(p.relative_to(root))
        for pkg in ("gcs_core", "gcs_tui")
        for p in (root / pkg).rglob("*.py")
        if str(p.relative_to(root)) not in allowed and pattern.search(p.read_text(encoding="utf-8"))
    ]
    assert offenders == []


@pytest.mark.parametrize("exchange", [True, False])
def test_atomic_directory_replaces_or_leaves_untouched(tmp_path, monkeypatch, exchange):
    """A staged directory replaces the old one (one-step exchange, or two renames where the
    system has none); a failure inside leaves the old one as it was and no stage behind."""
    from gcs_core import fileperm

    if not exchange:
        monkeypatch.setattr(fileperm, "_exchange", lambda a, b: False)
    out = tmp_path / "mission"
    for version in ("1", "2"):
        with fileperm.atomic_directory(out) as stage:
            (stage / "mission.toml").write_text(version)
        assert (out / "mission.toml").read_text() == version
        assert (out.stat().st_mode & 0o777) == 0o755
    with pytest.raises(RuntimeError):
        with fileperm.atomic_directory(out) as stage:
            (stage / "mission.toml").write_text("3")
            raise RuntimeError("half written")
    assert (out / "mission.toml").read_text() == "2"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mission"]
