"""Appends (gcs_core.io.h5append): every object checked the first time a process meets a
file's bytes, never again for the same bytes, always again for changed bytes; the cost of an
append does not grow object by object with the entries stored."""

from __future__ import annotations

import time

import pytest
from untrusted_cases import append, craft_scds, scds_with_versions

from gcs_core.errors import DataFileError
from gcs_core.io import h5append, scds


@pytest.fixture
def walks(monkeypatch):
    """How many times the object-by-object check ran."""
    count = {"n": 0}
    real = h5append.check_objects

    def counted(*args, **kw):
        count["n"] += 1
        return real(*args, **kw)

    monkeypatch.setattr(h5append, "check_objects", counted)
    monkeypatch.setattr(h5append, "_CHECKED", {})  # as a fresh process
    return count


def test_bytes_this_process_wrote_are_not_walked_again(tmp_path, walks):
    path = scds_with_versions(tmp_path / "c.h5", 3)
    assert walks["n"] == 0  # the file was made here: its bytes are the ones this process wrote
    h5append._CHECKED.clear()  # another process: the first append walks the file, the next ones not
    append(path, 3)
    append(path, 4)
    assert walks["n"] == 1
    assert [v.version for v in scds.list_versions(path)] == [1, 2, 3, 4, 5]


def test_changed_bytes_are_walked_again_and_refused(tmp_path, walks):
    path = scds_with_versions(tmp_path / "c.h5", 2)
    craft_scds(path, "fletcher_chunk")  # a corrupt chunk under a valid (recomputed) SHA-256
    before = path.read_bytes()
    with pytest.raises(DataFileError, match="fails its checksum.*refusing to append"):
        append(path, 5)
    assert walks["n"] == 1 and path.read_bytes() == before


def test_earlier_versions_read_back_the_same_after_many_appends(tmp_path):
    path = scds_with_versions(tmp_path / "c.h5", 1)
    first = scds.read_version(path, 1)
    for k in range(1, 30):
        append(path, k)
    again = scds.read_version(path, 1)
    assert again.params == first.params and again.provenance == first.provenance
    assert scds.read_version(path).version == 30


def test_an_append_costs_about_the_same_with_60_entries_as_with_5(tmp_path):
    """The earlier copy grew by ~2 ms per entry stored (120 ms more at 60); allow 4x noise."""
    path = scds_with_versions(tmp_path / "c.h5", 5)

    def one() -> float:
        t = time.process_time()
        append(path, 0)
        return time.process_time() - t

    early = min(one() for _ in range(3))
    for k in range(52):
        append(path, k)
    late = min(one() for _ in range(3))
    assert late < 4.0 * early + 0.02, (early, late)
