"""False alarms of discovery on fully modelled missions (issue 3).

"On nominal missions whose physics is fully modeled, discovery adds nothing on at least 95 %
of seeds. The test runs enough seeds to show it."

Missions: ``SEEDS`` = 100 nominal missions (data book = truth, real physics on in both the
simulator and the analysis config), the attitude mode rotating with the seed: Sun-pointing,
inertial and Earth-pointing three-axis missions of 30 minutes, and spinners of one hour
(25 of each). Each is fitted and :meth:`Analysis.discover` runs with the default
family-wise level (α = 0.001, Bonferroni over the candidates); an *alarm* is a seed on which
discovery adds any effect.

How many seeds "show it". Let p be the alarm rate. With k alarms in n seeds, the one-sided
95 % (Clopper–Pearson) upper confidence bound on p is the 0.95 quantile of
Beta(k + 1, n − k). The claim p < 5 % is shown when that bound is below 5 %:

* n = 60 shows it only with k = 0 (bound 4.9 %; the rule of three, 3/n); k = 1 gives 7.7 %;
* n = 100 shows it with k ≤ 1 (k = 0: 3.0 %, k = 1: 4.7 %; k = 2 gives 6.2 %).

So the test runs 100 seeds and tolerates at most ``MAX_ALARMS`` = 1, asserting the bound
itself. Expected: an engine whose χ² statistics are right alarms on about α = 0.1 % of
seeds, so k = 0 is the typical outcome.

Aggregation across xdist workers: each seed is its own test item (so ``-n 2`` spreads them);
it writes its outcome to a directory shared by the session's workers and then counts the
alarms recorded so far. The item that records alarm number ``MAX_ALARMS + 1`` sees it and
fails, so the session passes exactly when the total is within the allowance. An alarm
within the allowance is reported as a warning naming the effect added.

Scope: 30-minute three-axis missions with the default (whole-span) method, which carries
the gyro noise as process noise. On two-hour inertial missions with the default gyro
noise, batch discovery (``method = "batch"``) adds an effect on 5 of 40 seeds (100–139: FHST1/FSS1
time offsets, FSS1 harmonic), because the batch fit propagates
the attitude with the gyros at Q = 0: the gyro's angle and rate random walks leave slow
attitude wander in the residuals that the χ² statistics take for white noise (the session
warns and recommends ``method = "kalman"``). The same seeds with a noiseless gyro add
nothing. :func:`test_long_mission_false_alarm_from_gyro_noise` pins one such seed: the
default method adds nothing there, the batch still alarms (with its computed warning), and
the noiseless control adds nothing. With ``method = "kalman"`` the score is
formed from the smoother's residuals (:func:`~gcs_core.diagnosis.ranking.rank_candidates`,
``smoothed``) and the same 40 two-hour inertial seeds add nothing
(:func:`test_long_inertial_missions_with_the_kalman_method_add_nothing`; 0 of 40 bounds
the rate below 7.2 % at 95 %, and below the 5 % requirement together with the 100 seeds
above, 1 alarm allowed in 140).

References
----------
Clopper, C. J. & Pearson, E. S., "The use of confidence or fiducial limits illustrated in
the case of the binomial", Biometrika 26(4), 1934. Hanley, J. A. & Lippman-Hand, A., "If
nothing goes wrong, is everything all right?", JAMA 249(13), 1983 (rule of three).
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import pytest
from scipy import stats
from test_truth_recovery import ONE_HOUR, threeaxis

from gcs_core.config_schema import AnalysisConfig
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import spinner_nominal
from gcs_core.sim.writer import write_mission

SEEDS = range(100)
MAX_ALARMS = 1
#: the issue-3 requirement: alarm rate below 5 %, shown at 95 % confidence
required_rate = 0.05
confidence = 0.95
KINDS = ("sun_pointing", "inertial", "earth_pointing", "spinning")
THREE_AXIS_SECONDS = 1800.0
SPINNER_SECONDS = 3600.0


def alarm_rate_upper_bound(alarms: int, seeds: int, level: float = confidence) -> float:
    """One-sided Clopper–Pearson upper bound on a binomial rate: Beta(k+1, n−k) quantile."""
    return 1.0 if alarms >= seeds else float(stats.beta.ppf(level, alarms + 1, seeds - alarms))


def test_seed_count_shows_the_requirement():
    """The plan itself: 100 seeds with the allowed alarms bound the rate below 5 %."""
    assert alarm_rate_upper_bound(MAX_ALARMS, len(SEEDS)) < required_rate
    assert alarm_rate_upper_bound(MAX_ALARMS + 1, len(SEEDS)) >= required_rate


def kind_of(seed: int) -> str:
    return KINDS[seed % len(KINDS)]


def nominal(seed: int):
    if kind_of(seed) == "spinning":
        return spinner_nominal(seed=seed, duration_s=SPINNER_SECONDS)
    return threeaxis(kind_of(seed), seed, THREE_AXIS_SECONDS)


@pytest.fixture(scope="session")
def outcomes_dir(tmp_path_factory) -> Path:
    """A directory shared by every xdist worker of this session (fresh per session)."""
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    d = root / "false-alarm-outcomes"
    d.mkdir(exist_ok=True)
    return d


@pytest.mark.parametrize("seed", SEEDS, ids=[f"{kind_of(s)}-{s}" for s in SEEDS])
def test_discovery_adds_nothing_on_nominal_missions(seed, tmp_path, outcomes_dir):
    mission = write_mission(nominal(seed), tmp_path / "mission", truth_path=tmp_path / "truth.json")
    a = Analysis(AnalysisConfig(mission=mission))
    a.fit()
    a.discover()
    added = [s.effect for s in a.steps if s.action == "add"]
    record = {"seed": seed, "kind": kind_of(seed), "added": added, "stop": a.stop_reason}
    tmp = outcomes_dir / f".seed-{seed}.tmp"
    tmp.write_text(json.dumps(record))
    tmp.replace(outcomes_dir / f"seed-{seed}.json")  # atomic: readers see whole files
    if added:
        warnings.warn(f"false alarm on nominal {kind_of(seed)} seed {seed}: added {added}", stacklevel=2)
    recorded = [json.loads(p.read_text()) for p in outcomes_dir.glob("seed-*.json")]
    alarms = [r for r in recorded if r["added"]]
    assert len(alarms) <= MAX_ALARMS, (
        f"{len(alarms)} false alarms so far (allowed {MAX_ALARMS} in {len(SEEDS)} seeds): "
        + "; ".join(f"{r['kind']} seed {r['seed']} added {r['added']}" for r in alarms)
    )


def _discover(cfg, folder: Path) -> list[str]:
    mission = write_mission(cfg, folder / "mission", truth_path=folder / "truth.json")
    a = Analysis(AnalysisConfig(mission=mission))
    a.fit()
    a.discover()
    return [s.effect for s in a.steps if s.action == "add"]


LONG_SEED = 116  # inertial, 2 h: discovery adds FHST1.time_offset (module docstring)


def test_long_mission_false_alarm_from_gyro_noise(tmp_path):
    """The seed on which the batch (gyro taken as exact) adds FHST1.time_offset: the default
    whole-span fit carries the gyro noise as process noise and adds nothing."""
    assert _discover(threeaxis("inertial", LONG_SEED, 2 * ONE_HOUR), tmp_path) == []


def test_long_mission_false_alarm_with_the_batch_method(tmp_path):
    """The same seed with ``method = "batch"``: the alarm the whole-span fit removes, and the
    batch's computed warning about the wander it ignores."""
    cfg = threeaxis("inertial", LONG_SEED, 2 * ONE_HOUR)
    mission = write_mission(cfg, tmp_path / "mission", truth_path=tmp_path / "truth.json")
    a = Analysis(AnalysisConfig(mission=mission, method="batch"))
    a.fit()
    assert any("gyro noise" in w for w in a.warnings), a.warnings
    a.discover()
    assert [s.effect for s in a.steps if s.action == "add"] != []


def test_long_mission_without_gyro_noise_adds_nothing(tmp_path):
    """Control of the expected failure above: the same seed, noiseless gyro, no alarm."""
    cfg = threeaxis("inertial", LONG_SEED, 2 * ONE_HOUR)
    cfg.sensor("IRU").true.update(arw=0.0, rrw=0.0)
    assert _discover(cfg, tmp_path) == []


LONG_SEEDS = range(100, 140)


@pytest.mark.slow
@pytest.mark.parametrize("seed", LONG_SEEDS)
def test_long_inertial_missions_with_the_kalman_method_add_nothing(seed, tmp_path):
    """Two-hour inertial missions (where the batch alarms on 5 of these 40 seeds): the
    Kalman method models the gyro noise and its smoothed residuals carry no wander."""
    mission = write_mission(
        threeaxis("inertial", seed, 2 * ONE_HOUR), tmp_path / "mission", truth_path=tmp_path / "truth.json"
    )
    a = Analysis(AnalysisConfig(mission=mission, method="kalman"))
    a.fit()
    a.discover()
    assert [s.effect for s in a.steps if s.action == "add"] == [], a.stop_reason


def test_kalman_long_seed_count_bounds_the_rate():
    assert alarm_rate_upper_bound(0, len(LONG_SEEDS)) < 0.075
