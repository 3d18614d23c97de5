"""The config reference (docs/reference/config.md) is generated from the config's fields:
every key has documentation, every bound it lists is the one the loader enforces, and the
committed file is what the generator writes (gcs_core/config_reference.py)."""

from __future__ import annotations

from dataclasses import field, fields, make_dataclass

import pytest
from repo_paths import ROOT

from gcs_core import config_reference as R
from gcs_core.config import config_from_dict
from gcs_core.config_schema import PLANNING_TABLES, TABLES
from gcs_core.errors import ConfigError

REGENERATE = f"regenerate it: {R.COMMAND}"


def test_every_key_is_documented():
    missing = R.undocumented()
    assert not missing, f"give these config keys metadata=_doc(...) in gcs_core/config.py: {missing}"


def test_a_key_added_without_documentation_is_caught():
    Table = make_dataclass("Table", [("new_key", float, field(default=1.0))])
    assert R.undocumented([("filter.new_key", fields(Table)[0])]) == ["filter.new_key"]


def test_every_table_key_is_in_the_reference():
    text = R.render()
    for table, keys in {**TABLES, **PLANNING_TABLES}.items():
        assert f"## [{table}]" in text
        for k in keys:
            assert f"`{table}.{k}`" in text, f"{table}.{k} is not in the reference"
    assert set(PLANNING_TABLES) == set(R.PLANNING_DOCS)
    for table, keys in PLANNING_TABLES.items():
        assert set(keys) == set(R.PLANNING_DOCS[table]), f"document [{table}]'s keys in PLANNING_DOCS"


def test_the_committed_reference_is_current():
    path = ROOT / R.REFERENCE
    assert path.is_file(), f"docs/reference/config.md is missing; {REGENERATE}"
    assert path.read_text() == R.render(), f"docs/reference/config.md is stale; {REGENERATE}"


def _document(key: str, value) -> dict:
    """A config document setting ``key`` (as the reference spells it) to ``value``."""
    doc: dict = {"analysis": {"mission": "m"}}
    table, _, rest = key.partition(".")
    if key == "filter.edit_k_sensor":
        doc["filter"] = {"edit_k_sensor": {"TAM1": value}}
    elif rest.startswith('elements."NAME".'):
        doc["state"] = {"elements": {"TAM1.bias_x": {rest.rsplit(".", 1)[1]: value}}}
    elif rest.startswith("maneuvers[i]."):
        man = {"start": 0.0, "duration": 60.0, "axis": "yaw", "rate_deg_s": 0.1, rest.rsplit(".", 1)[1]: value}
        doc["prediction"] = {"maneuvers": [man]}
    else:
        doc.setdefault(table, {})[rest] = value
    return doc


def _probes(meta) -> tuple[list, list]:
    """(values the bounds allow, values they refuse)."""
    ok, bad = [], []
    if meta.get("choices"):
        ok += list(meta["choices"])
        bad.append("not-a-choice")
    lo, hi = meta.get("lo"), meta.get("hi")
    if meta.get("positive"):
        bad.append(0.0)
        ok.append(hi if hi is not None else 1e-6)
    if lo is not None:
        ok.append(lo)
        bad.append(lo - max(1e-3, abs(lo) * 1e-3))
    if hi is not None:
        ok.append(hi)
        bad.append(hi + max(1e-3, abs(hi) * 1e-3))
    if meta.get("integer"):
        bad.append((lo if lo is not None else 1) + 0.5)
    return ok, bad


BOUNDED = [(k, f.metadata) for k, f in R.key_fields() if R.bounds(f.metadata) != "—"]


@pytest.mark.parametrize(("key", "meta"), BOUNDED, ids=[k for k, _ in BOUNDED])
def test_each_documented_bound_is_enforced(key, meta):
    ok, bad = _probes(meta)
    for v in ok:
        config_from_dict(_document(key, v))
    for v in bad:
        with pytest.raises(ConfigError) as info:
            config_from_dict(_document(key, v))
        named = info.value.key or ""
        assert named.split(".")[-1] == key.split(".")[-1] or named == "filter.edit_k_sensor.TAM1", (key, v, named)
