"""``--scheduler`` handled like any other input (issue 24), on loopback addresses only.

* A port nobody listens on, a plain TCP service that sends garbage, and one that accepts
  and says nothing: one line naming ``--scheduler``, exit 2, within 10 s each.
* A real scheduler started here (``dask.distributed.LocalCluster`` on 127.0.0.1): the
  same numbers as the serial run, with the plan's files moved away before the tasks run
  (the work travels with the tasks; the workers read none of this machine's paths).
"""

from __future__ import annotations

import shutil
import socket
import threading
import time

import pytest
from repo_paths import ROOT

from gcs_core.config import load_config
from gcs_tui.cli.commands import main

CONFIG = ROOT / "sample_data" / "trade" / "smm-tam-bias.toml"
#: the acceptance: an answer within this many seconds
within_10_s = 10.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Service:
    """A plain TCP server on 127.0.0.1 that accepts and sends ``reply`` (or nothing),
    then holds the connection open."""

    def __init__(self, reply: bytes):
        self.reply = reply
        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.conns: list[socket.socket] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.stop.is_set():
            try:
                c, _ = self.sock.accept()
            except OSError:
                continue
            self.conns.append(c)
            if self.reply:
                try:
                    c.sendall(self.reply)
                except OSError:
                    pass

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=2)
        for c in self.conns:
            c.close()
        self.sock.close()


def _trade_at(address: str, capsys) -> tuple[int, str, float]:
    t0 = time.monotonic()
    code = main(["trade", str(CONFIG), "--vary", "span_min=10", "--vary", "start_min=0", "--scheduler", address])
    elapsed = time.monotonic() - t0
    return code, capsys.readouterr().err, elapsed


def _one_line_exit_2(code: int, err: str, elapsed: float) -> None:
    lines = [ln for ln in err.splitlines() if ln.startswith("gcs: ") and "error" in ln]
    assert code == 2, err
    assert len(lines) == 1 and "--scheduler" in lines[0], err
    assert "Traceback" not in err and "internal error" not in err, err
    assert elapsed <= within_10_s, elapsed


def test_dead_port_is_one_line_exit_2_within_10_s(capsys):
    pytest.importorskip("distributed")
    _one_line_exit_2(*_trade_at(f"tcp://127.0.0.1:{_free_port()}", capsys))


@pytest.mark.parametrize("reply", [b"", b"HTTP/1.1 200 OK\r\n\r\n" + bytes(range(256)) * 4], ids=["silent", "garbage"])
def test_a_service_that_is_not_dask_is_one_line_exit_2_within_10_s(reply, capsys):
    pytest.importorskip("distributed")
    svc = _Service(reply)
    try:
        _one_line_exit_2(*_trade_at(f"tcp://127.0.0.1:{svc.port}", capsys))
    finally:
        svc.close()


def test_bad_address_is_one_line(capsys):
    code = main(["trade", str(CONFIG), "--vary", "span_min=10", "--scheduler", "udp://127.0.0.1:1"])
    assert code == 2 and "--scheduler" in capsys.readouterr().err


def test_real_scheduler_identical_to_serial_with_the_files_gone(tmp_path):
    distributed = pytest.importorskip("distributed")
    from gcs_core.trade.run import run_study
    from gcs_core.trade.study import definition_from_config

    # the plan and its mission in a folder of their own, moved away once read
    work = tmp_path / "plan"
    shutil.copytree(ROOT / "sample_data" / "missions" / "nominal-sunpoint", work / "mission")
    text = CONFIG.read_text().replace('"../missions/nominal-sunpoint"', '"mission"')
    (work / "study.toml").write_text(text)
    vary = {"span_min": (10, 20), "start_min": (0, 30)}
    serial = run_study(definition_from_config(load_config(work / "study.toml"), vary))
    defn = definition_from_config(load_config(work / "study.toml"), vary).with_source()
    work.rename(tmp_path / "gone")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        remote = run_study(defn, scheduler=cluster.scheduler_address, batch=1)
    key = lambda rows: [(r.index, r.plan_id, r.sigma, r.noise_only, r.status) for r in rows]
    assert key(remote) == key(serial)
    assert all(r.status == "ok" for r in remote)
