"""Generic drift families (issue 26): partials against finite differences, the form of the
prediction, and the names.

A family ``<effect>_vs_<channel>`` wraps a model (:mod:`gcs_core.models.drift`); its
partials are checked with the shared checker on the model fixtures, with the families'
coefficients non-zero, for an aux channel, the orbit phase and time.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from model_fixtures import CASES

from gcs_core.diagnosis.families import family_name, offered_for
from gcs_core.diagnosis.structure import Dependency, catalogue_forms
from gcs_core.models.checks import CENTRAL_DIFFERENCE_RTOL, assert_partials_match, check_partials
from gcs_core.models.drift import DriftingModel, drifting_params, with_families

TYPES = ("magnetometer", "star_tracker", "fine_sun", "coarse_sun")


def _wrapped(case: str, rng):
    model, geom, params = CASES[case](rng)
    n = geom.n
    t = np.sort(rng.uniform(0.0, 7200.0, n))
    geom = dataclasses.replace(geom, t=t, aux={**dict(geom.aux), "tam_temp": 22.0 + 3.0 * np.sin(t / 900.0)})
    sd = SimpleNamespace(model=model, geom=geom, t=t, n=n)
    fams = [f"{eff}_vs_{tag}" for eff in drifting_params(model) for tag in ("tam_temp", "orbit1", "time")]
    wrapped = with_families(sd, fams, lambda tt: np.mod(tt / 5700.0 * 2 * np.pi, 2 * np.pi))
    assert isinstance(wrapped, DriftingModel)
    p = dict(params)
    for name, (base, _, _) in wrapped.terms.items():
        scale = next(s.sigma for s in model.parameters() if s.name == base)
        p[name] = 0.05 * scale * rng.standard_normal()
    return model, wrapped, geom, params, p


@pytest.mark.parametrize("case", TYPES)
def test_family_partials_match_finite_differences(case):
    """The families' partials are exact for the prediction (1) at any coefficients; the
    attitude's and the wrapped parameters' are exact where the drift is zero (first order
    in the drift elsewhere: they leave out ∂(k x ∂h/∂p)/∂θ, the module's stated order)."""
    _, wrapped, geom, params, p = _wrapped(case, np.random.default_rng(3))
    report = check_partials(wrapped, geom, p, scheme="central", rtol=CENTRAL_DIFFERENCE_RTOL)
    bad = [e.name for e in report.elements if not e.ok and e.name in wrapped.terms]
    assert not bad, report.summary()
    assert {e.name for e in report.elements} >= set(wrapped.terms)
    assert_partials_match(wrapped, geom, params, scheme="central", rtol=CENTRAL_DIFFERENCE_RTOL)


@pytest.mark.parametrize("case", TYPES)
def test_family_adds_first_order_drift(case):
    """y = h(p) + Σ k x ∂h/∂p, and zero coefficients give the wrapped model's prediction."""
    model, wrapped, geom, params, p = _wrapped(case, np.random.default_rng(5))
    base = model.predict(geom, params)
    zero = wrapped.predict(geom, params)
    np.testing.assert_allclose(zero.y, base.y, rtol=0, atol=0, equal_nan=True)
    full = wrapped.predict(geom, p)
    expect = np.array(base.y)
    for name, (pname, tag, j) in wrapped.terms.items():
        expect += p[name] * wrapped.X[tag][:, j][:, None] * np.nan_to_num(base.d_par[pname])
    np.testing.assert_allclose(full.y, expect, rtol=1e-12, atol=1e-15, equal_nan=True)


def test_names_say_physics_and_unit():
    assert family_name("alignment_vs_tam_temp") == "thermo-elastic bending, arcsec per °C"
    assert family_name("scale_vs_time") == "gain drift (ageing), ppm per hour"
    assert family_name("bias_vs_orbit1", "nT").startswith("a bias cycling over the orbit, nT")
    assert family_name("alignment") is None


def test_elements_carry_the_unit_of_their_channel():
    from gcs_core.models.drift import family_unit

    assert family_unit("rad", "tam_temp") == "rad/degC"
    assert family_unit("rad", "orbit1") == "rad"  # an amplitude
    assert family_unit("nT", "time") == "nT/h"
    assert family_unit("1", "mtb_x") == "1 per unit of mtb_x"


def test_offers_on_the_channel_and_its_aliases():
    model, *_ = CASES["star_tracker"](np.random.default_rng(0))
    dep = Dependency(
        "FHST1", "h", "rad", "aux:tam_temp", "tam_temp", "aux", "°C", np.zeros(2), np.zeros(2), np.ones(2),
        10.0, (1.0, 100.0), 1.0, 1e-9, aliases=("orbit_phase",),
    )  # fmt: skip
    offered = offered_for(dep, model, aliases=dep.aliases)
    assert "alignment_vs_tam_temp" in offered and "alignment_vs_orbit1" in offered
    assert "alignment_vs_orbit2" in offered and "scale_vs_tam_temp" in offered


def test_a_gyro_bias_following_a_heater_is_named_with_its_physics_and_unit():
    assert family_name("bias_vs_iru_heater", "rad/s") == "bias step with the heater, °/h per unit of iru_heater"


def test_only_switches_offer_the_gyro_its_bias_step():
    """A sensor's residual following the time integral of a switch, or the gyro's own score
    test on the switch, offers the gyro's ``bias_vs_<switch>`` and nothing else of the gyro's;
    a torquer of two levels on a short span is not a switch."""
    from gcs_core.diagnosis.channels import switch_channels
    from gcs_core.diagnosis.families import families_from

    def dep(sensor, channel, kind):
        return Dependency(
            sensor, "h", "rad", channel, channel.split(":")[-1], kind, "s", np.zeros(2), np.zeros(2), np.ones(2),
            10.0, (1.0, 100.0), 1.0, 1e-9,
        )  # fmt: skip

    model, *_ = CASES["star_tracker"](np.random.default_rng(0))
    models = {"FHST1": model}
    assert families_from([dep("FHST1", "int:iru_heater", "aux_integral")], models, gyro="IRU") == {
        "IRU": ("bias_vs_iru_heater",)
    }
    assert families_from([dep("IRU", "aux:iru_heater", "aux")], models, gyro="IRU") == {"IRU": ("bias_vs_iru_heater",)}
    assert families_from([dep("FHST1", "int:iru_heater", "aux_integral")], models, gyro=None) == {}
    columns = {
        "t": np.arange(6.0),
        "iru_heater": np.array([0, 1, 1, 0, 0, 1.0]),
        "mtb_x": np.array([0, 60, 0, 60, 0, 0.0]),
    }
    aux = type("Aux", (), {"t": columns["t"], "columns": columns, "__len__": lambda self: 6})()
    assert switch_channels(aux) == ("iru_heater",)


def test_catalogue_forms_keep_the_catalogue_order():
    """A rate dependency names every sensor's time offset: in the catalogue's order, whatever
    the hash seed (a set's order made a report differ from run to run)."""
    ids = ["FSS1.time_offset", "TAM1.time_offset", "FHST1.time_offset", "FHST2.time_offset"]
    rate = SimpleNamespace(kind="rate", label="rate")
    assert catalogue_forms("FSS1", rate, ids) == tuple(ids)
    assert catalogue_forms("FSS1", rate, ids[:1] + ids[:0:-1]) == (ids[0], *ids[:0:-1])
