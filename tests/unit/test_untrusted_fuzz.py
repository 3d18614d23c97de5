"""Issue 23: a seeded slice of the untrusted-reader fuzzing of ``benchmarks/fuzz_readers.py``
(``--suite untrusted`` runs 10,000 cases per reader; docs/benchmarks.md has its numbers).

60 cases of each reader — the analysis config, mission.toml, SCDS files, the BROAD and
Astro Pi converters, names with control characters — end with no unhandled exception
(no exit-4 outcome) and nothing a terminal would obey printed.
"""

from __future__ import annotations

import importlib.util

from repo_paths import ROOT


def test_seeded_untrusted_fuzz_slice_has_no_unhandled_case(capsys):
    path = ROOT / "benchmarks" / "fuzz_readers.py"
    spec = importlib.util.spec_from_file_location("fuzz_readers_script_untrusted", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    unhandled = script.run_untrusted(60, seed=23)
    out = capsys.readouterr().out
    assert unhandled == 0, out
    assert "60 cases per reader" in out
    for reader in ("config", "mission.toml", "scds", "broad", "astropi", "names"):
        assert reader in out
