"""SIGKILL a process appending SCDS versions at random moments: the file must always open,
and every version written before the kill must be intact (h5store's atomic replace).

The appender is forked (h5py already imported, so each round starts at once) and reports
each confirmed version through a pipe in 8-byte writes (atomic below PIPE_BUF).
"""

from __future__ import annotations

import multiprocessing
import os
import select
import signal
import struct
import time
from pathlib import Path

import numpy as np
import pytest

from gcs_core.io import h5store, scds

N_PARAMS = 40


def version_params(number_hint: float) -> dict:
    return {f"S{i}.p": (number_hint + i, 0.1 * (i + 1), "1") for i in range(N_PARAMS)}


IN_WRITE = -1  # message: the child is inside the write of the new temporary file


def appender(path: str, fd: int, pause_in_write: bool = False) -> None:
    """Child: append versions forever; each version's values encode its number.

    With ``pause_in_write`` the child announces IN_WRITE and sleeps in the middle of
    writing the new file (after its first array), so that a kill lands exactly there.
    """
    if pause_in_write:
        real = h5store.write_array

        def slow_write_array(group, name, data, **kw):
            ds = real(group, name, data, **kw)
            os.write(fd, struct.pack("<q", IN_WRITE))
            time.sleep(30)
            return ds

        h5store.write_array = slow_write_array
    try:
        names = [f"S{i}.p" for i in range(N_PARAMS)]
        n = len(scds.list_versions(path)) if os.path.exists(path) else 0
        while True:
            n += 1
            got = scds.append_version(
                path,
                sensor_params=version_params(n),
                covariance=np.eye(N_PARAMS) * n,
                element_names=names,
                provenance={"note": f"v{n}", "data_t0": 0.0, "data_t1": 1.0},
            )
            if got != n:
                os._exit(4)
            os.write(fd, struct.pack("<q", n))
    except BaseException:  # noqa: BLE001 — the child reports any failure by its exit code
        os._exit(3)


def wait_for_first(read_fd: int, timeout: float = 20.0) -> list[int]:
    """Block until the child's first message (a confirmed version, or IN_WRITE)."""
    deadline = time.monotonic() + timeout
    data = b""
    while len(data) < 8 and time.monotonic() < deadline:
        ready, _, _ = select.select([read_fd], [], [], 0.05)
        if ready:
            chunk = os.read(read_fd, 8 - len(data))
            if not chunk:
                break
            data += chunk
    return [struct.unpack("<q", data)[0]] if len(data) == 8 else []


def confirmed(read_fd: int) -> list[int]:
    out = []
    os.set_blocking(read_fd, False)
    while True:
        try:
            chunk = os.read(read_fd, 8 * 1024)
        except BlockingIOError:
            break
        if not chunk:
            break
        out += [struct.unpack("<q", chunk[i : i + 8])[0] for i in range(0, len(chunk) - 7, 8)]
    return out


def check_file(path: str, at_least: int) -> int:
    """The file opens, its whole-file checksum holds, versions are 1..n, n >= at_least."""
    h5store.check_file(path, scds.FORMAT, max_version=scds.VERSION)
    versions = [v.version for v in scds.list_versions(path)]
    assert versions == list(range(1, len(versions) + 1))
    assert len(versions) >= at_least
    last = scds.read_version(path)
    assert last.params["S0.p"][0] == last.version and last.provenance["note"] == f"v{last.version}"
    return len(versions)


@pytest.mark.slow
@pytest.mark.parametrize("kills", [100])
def test_sigkill_while_appending_never_loses_a_version(tmp_path, kills):
    rng = np.random.default_rng(20240320)
    path = str(tmp_path / "cal.scds.h5")
    ctx = multiprocessing.get_context("fork")
    total_confirmed = 0
    n_versions = 0
    for _ in range(kills):
        read_fd, write_fd = os.pipe()
        proc = ctx.Process(target=appender, args=(path, write_fd), daemon=True)
        proc.start()
        os.close(write_fd)
        first = wait_for_first(read_fd)
        assert first, "the appender confirmed nothing"
        time.sleep(float(rng.uniform(0.0, 0.08)))  # about one append: any phase of it
        os.kill(proc.pid, signal.SIGKILL)
        proc.join()
        assert proc.exitcode == -signal.SIGKILL, "the appender died on its own"
        done = first + confirmed(read_fd)
        os.close(read_fd)
        total_confirmed = max([total_confirmed] + done)
        if not os.path.exists(path):
            assert total_confirmed == 0
            continue
        n_versions = check_file(path, total_confirmed)
        # at most the one version in flight can have landed unconfirmed
        assert n_versions <= total_confirmed + 1
    assert n_versions >= kills
    # every version ever written is intact, value for value, every chunk checksum holds
    h5store.verify(path, scds.FORMAT, max_version=scds.VERSION)
    for v in range(1, n_versions + 1):
        version = scds.read_version(path, v)
        assert version.params == version_params(v)
        np.testing.assert_array_equal(version.covariance, np.eye(N_PARAMS) * v)
    # a clean append afterwards removes the temporaries the kills left behind
    names = [f"S{i}.p" for i in range(N_PARAMS)]
    scds.append_version(
        path,
        sensor_params=version_params(n_versions + 1),
        covariance=np.eye(N_PARAMS),
        element_names=names,
        provenance={},
    )
    assert not list(tmp_path.glob(".*.tmp"))


def test_sigkill_in_the_middle_of_writing_the_new_file(tmp_path):
    """Deterministic: each kill lands while the temporary file is half written."""
    path = str(tmp_path / "cal.scds.h5")
    names = [f"S{i}.p" for i in range(N_PARAMS)]
    for v in (1, 2):
        scds.append_version(
            path,
            sensor_params=version_params(v),
            covariance=np.eye(N_PARAMS) * v,
            element_names=names,
            provenance={"note": f"v{v}"},
        )
    before = open(path, "rb").read()
    ctx = multiprocessing.get_context("fork")
    for _ in range(3):
        read_fd, write_fd = os.pipe()
        proc = ctx.Process(target=appender, args=(path, write_fd, True), daemon=True)
        proc.start()
        os.close(write_fd)
        assert wait_for_first(read_fd) == [IN_WRITE]
        assert list(tmp_path.glob(".*.tmp")), "no temporary file while writing"
        os.kill(proc.pid, signal.SIGKILL)
        proc.join()
        os.close(read_fd)
        assert open(path, "rb").read() == before  # untouched, byte for byte
        assert check_file(path, 2) == 2
    assert (
        scds.append_version(
            path,
            sensor_params=version_params(3),
            covariance=np.eye(N_PARAMS) * 3,
            element_names=names,
            provenance={"note": "v3"},
        )
        == 3
    )
    assert not list(tmp_path.glob(".*.tmp"))


# --- every other writer: one helper (gcs_core.fileperm), killed the same way ------------

TEXT_LINES = 20000  # ~0.5 MB a version: a kill lands inside the write more often than not


def _text(n: int) -> str:
    return "".join(f"{n},{i}\n" for i in range(TEXT_LINES))


def text_writer(path: str, fd: int) -> None:
    """Child: rewrite a text file forever through the writers that use write_atomic and
    atomic_open (a config or report, a CSV table); each version's lines name it."""
    from gcs_core.fileperm import atomic_open, write_atomic

    try:
        n = 0
        while True:
            n += 1
            if n % 2:
                write_atomic(path, _text(n))
            else:  # line by line, flushed: a kill lands mid-file
                with atomic_open(path, "w", newline="\n") as fh:
                    for i, line in enumerate(_text(n).splitlines(keepends=True)):
                        fh.write(line)
                        if i % 200 == 0:
                            fh.flush()
            os.write(fd, struct.pack("<q", n))
    except BaseException:  # noqa: BLE001 — the child reports any failure by its exit code
        os._exit(3)


def directory_writer(path: str, fd: int) -> None:
    """Child: replace a mission-like directory forever (convert's staged directory)."""
    from gcs_core.convert.common import staged_directory

    try:
        n = 0
        while True:
            n += 1
            with staged_directory(Path(path), overwrite=True) as stage:
                (stage / "telemetry").mkdir()
                for name in ("mission.toml", "telemetry/A.csv", "telemetry/B.csv"):
                    (stage / name).write_text(_text(n) if name.endswith(".csv") else f"# {n}\n")
            os.write(fd, struct.pack("<q", n))
    except BaseException:  # noqa: BLE001 — the child reports any failure by its exit code
        os._exit(3)


def _version_of_text(path: Path) -> int:
    lines = path.read_text().splitlines()
    assert len(lines) == TEXT_LINES, f"{path}: {len(lines)} lines"
    versions = {line.split(",")[0] for line in lines}
    assert len(versions) == 1, f"{path}: a mix of versions"
    return int(versions.pop())


def _kill_rounds(tmp_path, target, path: Path, check, kills: int, seed: int) -> int:
    """Start ``target(path, fd)``, kill it at a random moment, ``check(path)`` -> version;
    the version on disk is never older than the last confirmed one."""
    rng = np.random.default_rng(seed)
    ctx = multiprocessing.get_context("fork")
    last = 0
    for _ in range(kills):
        read_fd, write_fd = os.pipe()
        proc = ctx.Process(target=target, args=(str(path), write_fd), daemon=True)
        proc.start()
        os.close(write_fd)
        first = wait_for_first(read_fd)
        assert first, "the writer confirmed nothing"
        time.sleep(float(rng.uniform(0.0, 0.03)))
        os.kill(proc.pid, signal.SIGKILL)
        proc.join()
        assert proc.exitcode == -signal.SIGKILL, "the writer died on its own"
        done = first + confirmed(read_fd)
        os.close(read_fd)
        on_disk = check(path)
        assert on_disk >= max(done), (on_disk, max(done))
        assert on_disk <= max(done) + 1  # at most the one in flight landed
        last = on_disk
    return last


def test_sigkill_while_rewriting_a_text_file(tmp_path):
    """write_atomic / atomic_open (configs, reports, CSV tables, plots): after each kill
    the file is one whole version, with the usual permissions."""
    from gcs_core.fileperm import usual_mode

    path = tmp_path / "report.json"

    def check(p):
        assert (p.stat().st_mode & 0o777) == usual_mode()
        return _version_of_text(p)

    _kill_rounds(tmp_path, text_writer, path, check, kills=15, seed=7)


def test_sigkill_while_replacing_a_directory(tmp_path):
    """atomic_directory (converted missions): after each kill the directory is there and
    holds one whole version, every file of it."""
    path = tmp_path / "mission"

    def check(p):
        versions = {_version_of_text(p / "telemetry" / n) for n in ("A.csv", "B.csv")}
        versions.add(int((p / "mission.toml").read_text().split()[1]))
        assert len(versions) == 1, f"a mix of versions: {versions}"
        return versions.pop()

    _kill_rounds(tmp_path, directory_writer, path, check, kills=15, seed=8)
    left = [p.name for p in tmp_path.iterdir() if p.name != "mission"]
    assert all(n.startswith(".mission.") for n in left), left  # only hidden stages of killed writers
