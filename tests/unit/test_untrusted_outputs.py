"""Issue 23, "data lost or overwritten": each reproducer of the issue, and the checks that
answer it (output paths checked before work, --force on GCS's own directories only,
locks that follow no link and truncate nothing, SCDS appends that verify everything).
"""

from __future__ import annotations

import logging
import os
import shutil
import stat
from pathlib import Path

import numpy as np
import pytest
from repo_paths import SAMPLE_MISSIONS
from untrusted_cases import append, broad_trial, craft_scds, scds_with_versions

from gcs_core import fileperm
from gcs_core.convert import convert
from gcs_core.convert.common import MARKER
from gcs_core.errors import DataFileError, InputError
from gcs_core.io import h5store, locks, outputs, scds
from gcs_tui.cli import commands as cli

MISSION = SAMPLE_MISSIONS / "nominal-sunpoint"


@pytest.fixture
def history(tmp_path) -> Path:
    """A 3-version SCDS (the calibration history a typo must not destroy)."""
    return scds_with_versions(tmp_path / "calib.h5", 3)


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a command starts its work (reading the mission)."""

    def boom(*a, **k):
        raise AssertionError("the work started before the output paths were checked")

    monkeypatch.setattr("gcs_core.io.importer.load_mission", boom)
    monkeypatch.setattr("gcs_core.config.config_for", boom)


def _err(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    return err


# ------------------------------------------------------------------ item 1: typo'd paths
@pytest.mark.parametrize(
    "argv",
    [
        ["import", str(MISSION), "--sdf", "{h}"],
        ["import", str(MISSION), "--report", "{h}"],
        ["batch", str(MISSION), "--report", "{h}"],
        ["discover", str(MISSION), "--report", "{h}"],
        ["predict", str(MISSION), "--report", "{h}"],
        ["verify", str(MISSION), "--report", "{h}"],
        ["verify", str(MISSION), "--asf", "{h}"],
        ["batch", str(MISSION), "--plots", "{h}"],
    ],
)
def test_no_output_option_replaces_a_calibration_history(history, argv, capsys, no_work):
    before = history.read_bytes()
    code = cli.main(["-q", *[a.format(h=history) for a in argv]])
    assert code == 2
    assert "calibration history" in _err(capsys)
    assert history.read_bytes() == before
    assert len(scds.list_versions(history)) == 3


def test_the_engine_refuses_too(history, tmp_path):
    """write_sdf and the JSON writer refuse an SCDS even when called directly."""
    from gcs_core.io.importer import load_mission
    from gcs_core.io.sdf_write import write_sdf
    from gcs_core.reporting import write_json_atomic

    before = history.read_bytes()
    m = load_mission(MISSION)
    with pytest.raises(DataFileError, match="calibration history"):
        write_sdf(history, m)
    with pytest.raises(InputError, match="calibration history"):
        write_json_atomic(history, {"a": 1})
    assert history.read_bytes() == before
    # an SDF replaces an SDF (that is what --sdf is for)
    sdf = tmp_path / "m.sdf.h5"
    write_sdf(sdf, m)
    write_sdf(sdf, m)


def test_other_kinds_gcs_recognises_are_refused(tmp_path, capsys, no_work):
    broad = broad_trial(tmp_path / "trial.hdf5")
    mission = tmp_path / "mission"
    shutil.copytree(MISSION, mission)
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for target, words in (
        (broad, "HDF5 file not written by GCS"),
        (mission, "mission directory"),
        (fifo, "FIFO"),
    ):
        assert cli.main(["-q", "import", str(MISSION), "--report", str(target)]) == 2
        assert words in _err(capsys)
    assert cli.main(["-q", "batch", str(MISSION), "--report", str(tmp_path / "r.json"), "--plots", str(broad)]) == 2
    assert "not a folder" in _err(capsys)


def test_a_gcs_file_of_a_format_without_a_name_is_refused_too(tmp_path, capsys, no_work):
    from gcs_core.trade import store

    results = tmp_path / "study.h5"
    store.append_batch(results, store.TRADE, study="{}", digest="d", records=[{"index": 0}])
    assert outputs.file_kind(results) == "TRADE"
    assert cli.main(["-q", "import", str(MISSION), "--report", str(results)]) == 2
    assert "a GCS TRADE file" in _err(capsys)


def test_one_file_for_two_outputs_is_refused(tmp_path, capsys, no_work):
    r = tmp_path / "x.json"
    assert cli.main(["-q", "import", str(MISSION), "--sdf", str(r), "--report", str(r)]) == 2
    assert "named by both --sdf and --report" in _err(capsys)


# ------------------------------------------------------------------ item 10: checked first
def test_unwritable_outputs_are_refused_before_any_work(tmp_path, monkeypatch, capsys, no_work):
    ro = tmp_path / "ro"
    ro.mkdir()
    real = fileperm.tempfile.mkstemp

    def mkstemp(*a, dir=None, **k):  # root ignores chmod: refuse as a read-only folder would
        if dir is not None and Path(dir) == ro:
            raise PermissionError(13, "Permission denied")
        return real(*a, dir=dir, **k)

    monkeypatch.setattr(fileperm.tempfile, "mkstemp", mkstemp)
    for option, name in (("--report", "r.json"), ("--scds", "c.h5"), ("--plots", "plots")):
        assert cli.main(["-q", "batch", str(MISSION), option, str(ro / name)]) == 2
        assert "cannot write in folder" in _err(capsys)
    (tmp_path / "r.json").write_text("{}")
    (tmp_path / "r.json").chmod(0o444)
    assert cli.main(["-q", "batch", str(MISSION), "--report", str(tmp_path / "r.json")]) == 2
    assert "read-only" in _err(capsys)


# ------------------------------------------------------------------ item 2: --force
def test_force_never_deletes_the_source_or_a_foreign_directory(tmp_path, capsys):
    work = tmp_path / "DIR"
    work.mkdir()
    src = broad_trial(work / "trial.hdf5")
    (work / "notes.txt").write_text("mine")
    assert cli.main(["-q", "convert", "broad", str(src), "--out", str(work), "--force"]) == 2
    assert "holds the source" in _err(capsys)
    assert src.is_file() and (work / "notes.txt").read_text() == "mine"
    other = tmp_path / "other"
    other.mkdir()
    (other / "x").write_text("x")
    assert cli.main(["-q", "convert", "broad", str(src), "--out", str(other), "--force"]) == 2
    assert "not made by gcs convert" in _err(capsys)
    assert (other / "x").exists()
    # a directory GCS converted carries the marker and may be replaced
    out = tmp_path / "m"
    assert cli.main(["-q", "convert", "broad", str(src), "--out", str(out)]) == 0
    assert (out / MARKER).is_file()
    assert cli.main(["-q", "convert", "broad", str(src), "--out", str(out), "--force"]) == 0


def test_force_on_the_current_directory_is_exit_2_and_leaves_no_tmp(tmp_path, monkeypatch, capsys):
    src = broad_trial(tmp_path / "src.hdf5")
    here = tmp_path / "here"
    here.mkdir()
    (here / "keep").write_text("k")
    monkeypatch.chdir(here)
    assert cli.main(["-q", "convert", "broad", str(src), "--out", ".", "--force"]) == 2
    _err(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["here", "src.hdf5"]
    assert (here / "keep").exists()


# ------------------------------------------------------------------ item 4: lock files
def test_a_symlinked_lock_file_is_refused_and_its_target_untouched(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    cal = tmp_path / "cal.h5"
    (tmp_path / "cal.h5.lock").symlink_to(victim)
    with pytest.raises(DataFileError, match="symbolic link: refusing to follow it"):
        append(cal)
    assert victim.read_text() == "precious\n"
    assert not cal.exists()


def test_a_lock_file_that_is_not_a_lock_record_is_not_overwritten(tmp_path):
    cal = tmp_path / "cal.h5"
    lock = tmp_path / "cal.h5.lock"
    lock.write_text("someone's notes, much longer than a PID\n")
    with pytest.raises(DataFileError, match="more than a GCS lock record"):
        append(cal)
    assert lock.read_text() == "someone's notes, much longer than a PID\n"
    lock.unlink()
    other = tmp_path / "other.txt"
    other.write_text("1\n")
    os.link(other, lock)
    with pytest.raises(DataFileError, match="hard links"):
        append(cal)


def test_a_symlinked_scds_is_written_through_and_shares_one_lock(tmp_path):
    real = scds_with_versions(tmp_path / "real.h5", 1)
    link = tmp_path / "link.h5"
    link.symlink_to(real)
    assert append(link, 1) == 2
    assert link.is_symlink() and len(scds.list_versions(real)) == 2
    assert locks.lock_path(link) == locks.lock_path(real)
    assert not (tmp_path / "link.h5.lock").exists()
    # the lock record is rewritten in place, never truncated to nothing
    assert locks.lock_path(real).read_text().strip() == str(os.getpid())


# ------------------------------------------------------------------ item 5: the lock wait
def test_the_wait_grows_with_the_file_and_is_announced(tmp_path, monkeypatch, caplog):
    big = tmp_path / "big.h5"
    with open(big, "wb") as fh:
        fh.truncate(200_000_000)  # sparse: 200 MB
    assert locks.wait_s(big) >= locks.LOCK_WAIT_S + 99.0
    small = scds_with_versions(tmp_path / "s.h5", 1)
    import fcntl

    fd = os.open(locks.lock_path(small), os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_EX)  # another holder (a different open file description)
    monkeypatch.setattr(locks, "SAY_AFTER_S", 0.05)
    try:
        with caplog.at_level(logging.WARNING, logger="gcs_core.io.locks"):
            with pytest.raises(DataFileError, match="in use by another GCS process"):
                with locks.locked(small, exclusive=True, wait=0.3):
                    pass
        assert any("waiting for it, up to" in r.getMessage() for r in caplog.records)
    finally:
        os.close(fd)


def test_a_finished_fit_is_saved_beside_when_the_history_refuses_it(tmp_path, monkeypatch):
    from gcs_tui.cli.outputs import save_calibration_kept

    calls = []

    def save(a, path, note=""):
        calls.append(Path(path))
        if len(calls) == 1:
            raise DataFileError("is in use by another GCS process (pid 1)", file=path)
        return 1

    monkeypatch.setattr("gcs_core.calibration.save_calibration", save)
    version, where, problem = save_calibration_kept(object(), tmp_path / "cal.h5", "n")
    assert version == 1 and "in use" in problem
    assert where.parent == tmp_path and where.name.startswith("cal.h5.unsaved-")


# ------------------------------------------------------------------ item 6: SCDS internals
@pytest.mark.parametrize("craft", ["soft_link", "external_link", "versions_dataset", "version_dataset", "digits_30"])
def test_crafted_scds_is_refused_in_one_line(tmp_path, craft):
    path = scds_with_versions(tmp_path / "c.h5", 2)
    craft_scds(path, craft)
    before = path.read_bytes()
    for fn in (scds.list_versions, scds.read_version, lambda p: append(p, 9)):
        with pytest.raises(DataFileError) as info:
            fn(path)
        assert "\n" not in str(info.value)
    assert path.read_bytes() == before


def test_cli_exit_2_on_a_versions_dataset_before_the_fit(tmp_path, capsys, no_work):
    path = scds_with_versions(tmp_path / "c.h5", 1)
    craft_scds(path, "versions_dataset")
    assert cli.main(["-q", "batch", str(MISSION), "--scds", str(path)]) == 2
    assert "is a dataset, not a group" in _err(capsys)


def test_a_corrupt_fletcher32_chunk_under_a_valid_sha_is_never_appended_to(tmp_path):
    path = scds_with_versions(tmp_path / "c.h5", 2)
    craft_scds(path, "fletcher_chunk")
    h5store.check_file(path, "SCDS", max_version=1)  # the whole-file SHA holds
    before = path.read_bytes()
    with pytest.raises(DataFileError, match="fails its checksum.*refusing to append"):
        append(path, 5)
    assert path.read_bytes() == before


def test_versions_sort_as_numbers(tmp_path):
    path = scds_with_versions(tmp_path / "c.h5", 2)
    craft_scds(path, "digits_6")  # a version 100000 beside 00001, 00002
    assert scds.read_version(path).version == 100000
    assert [v.version for v in scds.list_versions(path)][-1] == 100000
    assert append(path, 3) == 100001


# ------------------------------------------------------------------ umask
def test_outputs_honour_the_umask(tmp_path):
    old = os.umask(0o077)
    try:
        src = broad_trial(tmp_path / "t.hdf5")
        out = tmp_path / "m"
        convert("broad", src, out)
        append(tmp_path / "c.h5")
        fileperm.write_atomic(tmp_path / "r.json", "{}")
        fileperm.write_atomic_set([(tmp_path / "p.txt", "x")])
    finally:
        os.umask(old)
    for p in [out, *out.rglob("*")]:
        mode = stat.S_IMODE(p.stat().st_mode)
        assert mode & 0o077 == 0, (p, oct(mode))
    for p in (tmp_path / "c.h5", tmp_path / "c.h5.lock", tmp_path / "r.json", tmp_path / "p.txt"):
        assert stat.S_IMODE(p.stat().st_mode) & 0o077 == 0, p


def test_a_plot_set_is_all_or_nothing(tmp_path, monkeypatch):
    files = [(tmp_path / f"p{k}.txt", "x" * 100) for k in range(5)]
    real = os.fsync
    count = {"n": 0}

    def fsync(fd):
        count["n"] += 1
        if count["n"] == 3:
            raise OSError(28, "No space left on device")
        return real(fd)

    monkeypatch.setattr(fileperm.os, "fsync", fsync)
    with pytest.raises(OSError):
        fileperm.write_atomic_set(files)
    assert list(tmp_path.iterdir()) == []


def test_disk_full_writing_an_sdf_is_one_line(tmp_path):
    """RLIMIT_FSIZE stands in for a full disk: the write fails with EFBIG part-way."""
    import subprocess
    import sys

    from repo_paths import ROOT

    script = (
        "import resource, signal, sys\n"
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (200000, 200000))\n"
        "from gcs_tui.cli.commands import main\n"
        f"sys.exit(main(['-q', 'import', {str(MISSION)!r}, '--sdf', {str(tmp_path / 'm.h5')!r}]))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.count("\n") == 1 and "cannot be written" in proc.stderr
    assert [p.name for p in tmp_path.iterdir()] in ([], ["m.h5.lock"])


def test_output_kind_is_sniffed_without_opening_a_fifo(tmp_path):
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    assert outputs.file_kind(fifo) == "fifo"
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    with pytest.raises(InputError, match="loop of symbolic links"):
        outputs.file_kind(loop)
    assert np.isscalar(locks.wait_s(tmp_path / "absent"))
