"""Predictor star models from a real catalog (seed §3.2.2, §4.3; gcs_core.predictor.stars).

Acceptance (the issue): "The predictor's σ for a data plan matches the calibration's
post-fit σ on simulated data for the same plan, within 15%." At an inertially fixed
pointing a tracker sees the same few stars for the whole span, so the σ of the FHST
scale factors depends on exactly which stars lie in its field: with the synthetic sky
the predictor was up to 24 % off, with the mission's own catalog (``star_catalog.csv``,
written by the simulator) it is within 10 % (benchmarks/predictor_vs_fit.py, 5 seeds).

The comparison holds for the elements the plan determines. ``FSS1.k_beta`` is not one
of them: the amplitude ``B3`` of ``B3 sin(k_β tan β)`` (Eq 4-23b) is 0 in the data book,
so ``k_β`` is held by default (``problem.unseen_at_prior``). Solved for, the plan gives it
no information and the predictor says so (``PredictionResult.undetermined``: σ = its a
priori), while the post-fit σ is linearized at the fitted ``B̂3`` (noise) and shrinks with
``B̂3²``: 3.2 to 4.9 against the a priori 5 over the benchmark's five seeds; seed 3 is
one where that post-fit σ is 13 % below the a priori.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gcs_core.config import ConfigError, config_from_dict, load_config, save_config
from gcs_core.config_schema import AnalysisConfig, Maneuver
from gcs_core.errors import InputError
from gcs_core.io.importer import load_mission
from gcs_core.io.types import Table
from gcs_core.predictor.plan import DataPlan
from gcs_core.predictor.predict import predict
from gcs_core.predictor.stars import STAR_CATALOG_FILE, Catalog, read_catalog, telemetry_catalog
from gcs_core.session import Analysis
from gcs_core.sim.config import Slew, ThreeAxisProfile
from gcs_core.sim.scenarios import nominal_threeaxis
from gcs_core.sim.stars import StarCatalog
from gcs_core.sim.writer import STAR_CATALOG_FILE as SIM_CATALOG_FILE
from gcs_core.sim.writer import write_mission
from gcs_core.units import DEG

FIFTEEN_PERCENT = 0.15
SPAN_S = 3600.0
SLEWS = [
    Slew(792.0, 600.0, "roll", 0.04, ramp_s=0.0),
    Slew(1620.0, 300.0, "pitch", 0.02, ramp_s=0.0),
    Slew(2160.0, 300.0, "yaw", -0.02, ramp_s=0.0),
    Slew(2700.0, 600.0, "roll", -0.04, ramp_s=0.0),
]
MANEUVERS = tuple(Maneuver(s.t_start, s.duration_s, s.axis, s.rate_deg_s) for s in SLEWS)
SEEDS = (1, 2, 3)


def inertial_mission(folder: Path, seed: int) -> tuple[Path, tuple[float, float, float]]:
    """One hour inertially fixed (body x at the Sun at the epoch), four maneuvers, no wobble."""
    cfg = nominal_threeaxis("inertial", seed=seed, duration_s=SPAN_S)
    rpy0 = tuple(cfg.attitude.rpy0_deg)
    cfg.attitude = ThreeAxisProfile(rpy0_deg=rpy0, wobble_amp_deg=(0.0, 0.0, 0.0), slews=list(SLEWS))
    return write_mission(cfg, folder / f"inertial-{seed}"), rpy0


@pytest.fixture(scope="module", params=SEEDS, ids=[f"seed{s}" for s in SEEDS])
def inertial(request, tmp_path_factory):
    mdir, rpy0 = inertial_mission(tmp_path_factory.mktemp("cat"), request.param)
    analysis = Analysis(AnalysisConfig(mission=mdir).with_changes(diagnosis={"holdout_fraction": 0.0}))
    fit = analysis.fit(holdout=False)
    plan = DataPlan(0.0, SPAN_S, step=60.0, rpy0=tuple(a * DEG for a in rpy0), maneuvers=MANEUVERS, stars="catalog")
    return analysis, fit, plan


def test_inertial_plan_with_the_catalog_matches_post_fit_sigma_within_15_percent(inertial):
    analysis, fit, plan = inertial
    assert fit.status == "converged"
    pred = predict(analysis.mission, plan=plan, method="whole_span")  # the fit's method
    assert pred.names == fit.solve_for
    ratio = pred.noise_only / np.sqrt(np.diag(fit.P))
    # k_beta is held (B3 is 0 in the data book); anything the plan does not determine is
    # flagged by the predictor, and the fit cannot know more than its a priori there
    assert "FSS1.k_beta" not in pred.names
    und = np.array([n in pred.undetermined for n in pred.names])
    prior = np.array([analysis.problem.state[n].sigma0 for n in pred.names])
    assert np.all(np.sqrt(np.diag(fit.P))[und] <= prior[und] * (1 + 1e-9))
    ratio = np.where(und, 1.0, ratio)
    worst = int(np.argmax(np.abs(ratio - 1.0)))
    assert np.all(np.abs(ratio - 1.0) < FIFTEEN_PERCENT), (pred.names[worst], ratio[worst])
    for name, r in fit.residuals.items():
        assert pred.frames[name] == pytest.approx(r.n, rel=0.01), name


def test_telemetry_stars_predict_like_the_catalog(inertial):
    """The stars the trackers reported are (nearly) the catalog stars in their fields."""
    analysis, fit, plan = inertial
    by_catalog = predict(analysis.mission, plan=plan)
    by_telemetry = predict(analysis.mission, plan=replace(plan, stars="telemetry"))
    fhst = [i for i, n in enumerate(by_catalog.names) if n.startswith("FHST")]
    ratio = by_telemetry.noise_only[fhst] / np.sqrt(np.diag(fit.P))[fhst]
    assert np.all(np.abs(ratio - 1.0) < FIFTEEN_PERCENT)
    assert by_telemetry.frames == by_catalog.frames


# ---------------------------------------------------------------------------- the file
@pytest.fixture(scope="module")
def small_mission(tmp_path_factory):
    cfg = nominal_threeaxis("inertial", seed=3, duration_s=600.0)
    return write_mission(cfg, tmp_path_factory.mktemp("small") / "m")


def test_simulator_writes_its_catalog_and_the_importer_ignores_it(small_mission):
    assert SIM_CATALOG_FILE == STAR_CATALOG_FILE
    sim = StarCatalog(nominal_threeaxis("inertial").catalog_seed)
    cat = read_catalog(small_mission / STAR_CATALOG_FILE)
    ten_microarcseconds = 1e-5 / 3600.0  # %.12g of a value below 360 deg: 9 decimals
    np.testing.assert_allclose(cat.ra_deg, sim.ra_deg, rtol=0, atol=ten_microarcseconds)
    np.testing.assert_allclose(cat.dec_deg, sim.dec_deg, rtol=0, atol=ten_microarcseconds)
    np.testing.assert_allclose(cat.mag, sim.mag, rtol=1e-11)
    mission = load_mission(small_mission)  # not named in mission.toml
    assert STAR_CATALOG_FILE not in {Path(s.telemetry).name for s in mission.spec.sensors}


def test_telemetry_source_collects_the_distinct_stars(small_mission):
    mission = load_mission(small_mission)
    tabs = [mission.telemetry[s.name] for s in mission.spec.sensors if s.type == "star_tracker"]
    cat = telemetry_catalog(tabs)
    reported = np.concatenate([np.column_stack([t.columns[c] for c in ("ra", "dec", "mag")]) for t in tabs])
    assert 0 < len(cat) < len(reported)  # each star reported many times
    assert len(cat) == len(np.unique(reported, axis=0))
    full = read_catalog(small_mission / STAR_CATALOG_FILE)
    one_arcsecond_deg = 1.0 / 3600.0
    d = np.abs(full.ra_deg[None, :] - cat.ra_deg[:, None]) + np.abs(full.dec_deg[None, :] - cat.dec_deg[:, None])
    assert np.all(d.min(axis=1) < one_arcsecond_deg)  # every one a catalog star
    # the same star in two rows (and two trackers) is one entry
    row = lambda *v: Table(
        Path("x.csv"),
        np.arange(len(v), dtype=float),
        {
            "ra": np.array([a for a, _, _ in v]),
            "dec": np.array([b for _, b, _ in v]),
            "mag": np.array([m for _, _, m in v]),
        },
        np.arange(len(v)),
    )
    two = telemetry_catalog([row((10.0, 20.0, 4.0), (10.0, 20.0, 4.0), (11.0, 20.0, 5.0)), row((11.0, 20.0, 5.0))])
    assert len(two) == 2 and isinstance(two, Catalog)
    assert telemetry_catalog([row()]) is None


@pytest.mark.parametrize(
    "text, line, column, words",
    [
        ("ra,dec,mag\n10.0,20.0,4.0\n10.0,abc,4.0\n", 3, 2, "not a number"),
        ("# a comment\nra,dec,mag\n\n# star 1\n10.0,20.0,4.0\n10.0,20.0\n", 6, 3, "missing column 3 'mag'"),
        ("ra,mag\n10.0,4.0\n", 1, "dec", "missing required column 'dec'"),
        ("ra,dec,mag\n400.0,20.0,4.0\n", 2, 1, "right ascension outside [0, 360] deg"),
        ("ra,dec,mag\n10.0,20.0,4.0\n10.0,-95.0,4.0\n", 3, 2, "declination outside [-90, 90] deg"),
        ("ra,dec,mag\n10.0,20.0,\n", 2, 3, "empty or nan value"),
        ("ra,dec,mag\n10.0,20.0,inf\n", 2, 3, "infinite value"),
        ("ra,dec,mag\n", 1, None, "no stars"),
        ("10.0,20.0,4.0\n", 1, 1, "no header line"),
    ],
)
def test_catalog_read_errors_name_file_line_and_column(tmp_path, text, line, column, words):
    path = tmp_path / "skymap.csv"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_catalog(path)
    e = err.value
    assert (Path(e.file), e.line, e.column) == (path, line, column)
    assert words in e.message and "\n" not in str(e)


def test_catalog_with_comments_and_extra_columns(tmp_path):
    path = tmp_path / "skymap.csv"
    path.write_text("# SKYMAP extract\nid,ra,dec,mag\n1,0.0,90.0,2.0\n# faint\n2,90.0,0.0,5.5\n")
    cat = read_catalog(path)
    np.testing.assert_allclose(cat.u_I, [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]], atol=1e-15)
    np.testing.assert_array_equal(cat.mag, [2.0, 5.5])
    with pytest.raises(InputError, match="not found"):
        read_catalog(tmp_path / "none.csv")


# ---------------------------------------------------------------------------- plan and config
def test_plan_validation_of_the_star_model(small_mission, tmp_path):
    with pytest.raises(InputError) as err:
        DataPlan(0.0, 600.0, stars="hipparcos")
    assert err.value.key == "prediction.stars"
    with pytest.raises(InputError) as err:
        DataPlan(0.0, 600.0, stars="sky", catalog=Path("skymap.csv"))
    assert err.value.key == "prediction.catalog"
    # stars = "catalog" without a path: the mission's star_catalog.csv ...
    mission = load_mission(small_mission)
    pred = predict(mission, plan=DataPlan(0.0, 600.0, step=60.0, stars="catalog"))
    assert pred.frames["FHST1"] > 0
    # ... and with none anywhere, one line naming prediction.catalog
    bare = replace(mission, spec=replace(mission.spec, root=tmp_path))
    with pytest.raises(InputError) as err:
        predict(bare, plan=DataPlan(0.0, 600.0, step=60.0, stars="catalog"))
    assert err.value.key == "prediction.catalog" and STAR_CATALOG_FILE in err.value.message
    with pytest.raises(InputError) as err:
        predict(mission, plan=DataPlan(0.0, 600.0, stars="catalog", catalog=Path("missing.csv")))
    assert err.value.key == "prediction.catalog" and Path(err.value.file) == small_mission / "missing.csv"
    # "telemetry" needs tracker telemetry
    no_tm = replace(mission, telemetry={k: v for k, v in mission.telemetry.items() if not k.startswith("FHST")})
    with pytest.raises(InputError) as err:
        predict(no_tm, plan=DataPlan(0.0, 600.0, step=60.0, stars="telemetry"))
    assert err.value.key == "prediction.stars"


def test_config_keys_stars_and_catalog(small_mission, tmp_path):
    base = {"analysis": {"mission": str(small_mission)}}
    cfg = config_from_dict({**base, "prediction": {"catalog": "star_catalog.csv"}}, path=tmp_path / "a.toml")
    assert cfg.prediction.catalog == small_mission / "star_catalog.csv"  # relative to the mission
    plan = DataPlan.from_config(cfg, span=(0.0, 600.0))
    assert (plan.stars, plan.catalog) == ("catalog", small_mission / "star_catalog.csv")
    assert DataPlan.from_config(cfg, span=(0.0, 600.0), stars="sky").catalog is None
    saved = load_config(save_config(cfg, tmp_path / "sub" / "saved.toml"))
    assert saved.prediction.catalog == cfg.prediction.catalog and saved.digest() == cfg.digest()
    tm = config_from_dict({**base, "prediction": {"stars": "telemetry"}})
    assert DataPlan.from_config(tm, span=(0.0, 600.0)).stars == "telemetry"
    assert DataPlan.from_config(config_from_dict(base), span=(0.0, 600.0)).stars == "sky"
    for table, key in (({"stars": "hipparcos"}, "prediction.stars"), ({"catalog": 3}, "prediction.catalog")):
        with pytest.raises(ConfigError) as err:
            config_from_dict({**base, "prediction": table})
        assert err.value.key == key
    # a catalog beside another star model: refused by the plan, naming the file and key
    odd = config_from_dict({**base, "prediction": {"stars": "sky", "catalog": "x.csv"}}, path=tmp_path / "b.toml")
    with pytest.raises(InputError) as err:
        DataPlan.from_config(odd, span=(0.0, 600.0))
    assert (err.value.key, err.value.file) == ("prediction.catalog", tmp_path / "b.toml")


def test_tracker_magnitude_limit_keeps_only_bright_candidates(small_mission):
    """Data-book ``mag_limit``: fainter catalog stars are no candidates. The simulator's
    catalog holds magnitudes 2 to 6: a limit of 1 leaves no star, one of 6 changes nothing."""
    mission = load_mission(small_mission)
    plan = DataPlan(0.0, 600.0, step=60.0, stars="catalog")

    def limited(m):
        sensors = tuple(
            replace(s, book={**s.book, "mag_limit": m}) if s.type == "star_tracker" else s for s in mission.spec.sensors
        )
        return predict(replace(mission, spec=replace(mission.spec, sensors=sensors)), plan=plan)

    full = predict(mission, plan=plan)
    assert full.frames["FHST1"] > 0
    assert "FHST1" not in limited(1.0).frames  # no frame finds a star
    np.testing.assert_array_equal(limited(6.0).sigma, full.sigma)
