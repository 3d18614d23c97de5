"""The issue-23 readers fuzzed by ``benchmarks/fuzz_readers.py --untrusted``.

Six readers, each given its own seeded cases (in-process, for speed):

* ``config`` — the analysis config (``gcs_core.config.load_config``) mutated byte-wise with
  hostile tokens (400- and 5000-digit integers, a BOM, controls, bidi, nan, inf);
* ``mission.toml`` — ``read_mission_spec`` on the same kind of mutations;
* ``scds`` — a valid SCDS with random bytes damaged, or crafted by h5py and re-certified
  (soft and external links, datasets for groups, 30-digit and non-digit versions, a bad
  fletcher32 chunk under a valid SHA-256): listed, read, and appended to (one case in four);
* ``broad`` — a BROAD-like trial with random bytes damaged or crafted types and shapes:
  read (``broad._read``) every case, converted in full one case in fifty;
* ``astropi`` — the Astro Pi CSV mutated: read as the converter reads it every case,
  converted in full one case in two hundred;
* ``names`` — mission and sensor names and keys holding control characters, C1 controls
  and bidi overrides: read, and the result or the refusal written through the ``gcs``
  command's output layer (``gcs import`` itself one case in twenty); nothing the terminal
  would obey may come out.

An outcome is *handled* when the reader returns or raises a ``GcsError`` whose message is
one line (exit 2 in the ``gcs`` command); anything else is *unhandled* and counts as an
exit-4 outcome (what the command would report as a bug in GCS).
"""

from __future__ import annotations

import contextlib
import io
import random
import re
import shutil
import sys
import traceback
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "helpers"))

import h5py
import numpy as np

from gcs_core.errors import GcsError
from gcs_core.textsafe import BIDI

READERS = ("config", "mission.toml", "scds", "broad", "astropi", "names")
#: what a terminal would obey, were it printed raw
RAW = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f" + BIDI + "]")
HOSTILE = [
    "\x1b]2;PWNED\x07",
    "\x1b]52;c;ZWNobyBwd25lZA==\x07",
    "\x1b[2J",
    "\x00",
    "\u202e",
    "\u2066",
    "\x9b31m",
    "\r",
    "\x7f",
    "\u2028",
    "é",
    "σ",
]
TOKENS = [
    b"9" * 400,
    b"-" + b"9" * 401,
    b"9" * 5000,
    b"\xef\xbb\xbf",
    b"nan",
    b"inf",
    b"1e400",
    b"\x00",
    b"\x1b]2;x\x07",
    "\u202e".encode(),
    b"=",
    b"[",
    b'"',
    b"\n",
    b"[[",
    b"0",
    b"-1",
    b"1e-320",
    b"true",
    b'"\\u001b"',
]


def mutate(rng: random.Random, data: bytes) -> bytes:
    for _ in range(rng.choice((1, 1, 1, 2, 3, 5))):
        p = rng.randint(0, len(data))
        kind = rng.random()
        if kind < 0.45:
            data = data[:p] + rng.choice(TOKENS) + data[p:]
        elif kind < 0.6:
            data = data[:p] + data[p + rng.randint(1, 30) :]
        elif kind < 0.8 and data:
            p = min(p, len(data) - 1)
            data = data[:p] + bytes([rng.randrange(256)]) + data[p + 1 :]
        else:  # a number replaced by a huge one
            m = list(re.finditer(rb"(?<![\w.])\d+(\.\d+)?", data))
            if m:
                g = rng.choice(m)
                data = data[: g.start()] + rng.choice(TOKENS[:3]) + data[g.end() :]
    return data


class Fuzzer:
    """Shared state: a work folder, the valid inputs, the counts."""

    def __init__(self, work: Path, seed: int):
        from untrusted_cases import broad_trial, scds_with_versions

        self.work, self.rng = work, random.Random(seed)
        self.counts: dict[str, dict[str, int]] = {r: {"accepted": 0, "refused": 0, "unhandled": 0} for r in READERS}
        self.examples: list[str] = []
        cfg = (REPO / "sample_data" / "configs" / "nominal-sunpoint.toml").read_text()
        self.config = cfg.replace('"../missions/nominal-sunpoint"', f'"{REPO}/sample_data/missions/nominal-sunpoint"')
        self.config_path = work / "c.toml"
        self.tiny = _tiny_mission(work / "tiny")
        self.toml = (self.tiny / "mission.toml").read_bytes()
        self.scds_good = scds_with_versions(work / "good.scds.h5", 2).read_bytes()
        self.broad_good = broad_trial(work / "good.hdf5").read_bytes()
        self.astropi_csv = (REPO / "tests" / "data" / "astropi" / "astropi_extract.csv").read_bytes()
        self.tle = REPO / "tests" / "data" / "astropi" / "iss-2022-01-31.tle"

    def case(self, reader: str, fn: Callable[[], object]) -> None:
        c = self.counts[reader]
        try:
            fn()
            c["accepted"] += 1
        except GcsError as err:
            if "\n" in str(err):
                c["unhandled"] += 1
                self.examples.append(f"{reader}: multi-line message {str(err)!r}")
            else:
                c["refused"] += 1
        except Exception:  # noqa: BLE001 — any other exception is what this fuzzer counts
            c["unhandled"] += 1
            self.examples.append(f"{reader}:\n" + traceback.format_exc(limit=5))

    # ------------------------------------------------------------------ readers
    def config_case(self) -> None:
        from gcs_core.config import load_config

        self.config_path.write_bytes(mutate(self.rng, self.config.encode()))
        self.case("config", lambda: load_config(self.config_path))

    def toml_case(self) -> None:
        from gcs_core.io.mission import read_mission_spec

        (self.tiny / "mission.toml").write_bytes(mutate(self.rng, self.toml))
        self.case("mission.toml", lambda: read_mission_spec(self.tiny))

    def scds_case(self) -> None:
        from untrusted_cases import CRAFTS, append, craft_scds

        from gcs_core.io import scds

        path = self.work / f"s{self.rng.randrange(10**9)}.scds.h5"
        path.write_bytes(self.scds_good)
        try:
            if self.rng.random() < 0.5:
                data = bytearray(self.scds_good)
                for _ in range(self.rng.randint(1, 8)):
                    data[self.rng.randrange(len(data))] = self.rng.randrange(256)
                path.write_bytes(bytes(data))
            else:
                for craft in self.rng.sample(CRAFTS, self.rng.randint(1, 2)):
                    try:
                        craft_scds(path, craft)
                    except Exception:  # noqa: BLE001 — crafting, not the reader: two crafts may collide
                        pass

            def read() -> None:
                scds.list_versions(path)
                scds.read_version(path)
                scds.read_version(path, self.rng.choice([1, 2, 99, 100000]))

            self.case("scds", read)
            if self.rng.random() < 0.25:
                self.case("scds", lambda: append(path, 7))
        finally:
            for p in (path, path.with_name(path.name + ".lock")):
                p.unlink(missing_ok=True)

    def broad_case(self) -> None:
        from gcs_core.convert import convert
        from gcs_core.convert.broad import _read

        src = self.work / "b.hdf5"
        if self.rng.random() < 0.6:
            data = bytearray(self.broad_good)
            for _ in range(self.rng.randint(1, 20)):
                data[self.rng.randrange(len(data))] = self.rng.randrange(256)
            src.write_bytes(bytes(data))
        else:
            src.write_bytes(self.broad_good)
            _craft_broad(src, self.rng)
        if self.rng.random() < 0.02:
            out = self.work / "bout"
            shutil.rmtree(out, ignore_errors=True)
            self.case("broad", lambda: convert("broad", src, out))
        else:
            self.case("broad", lambda: _read(src))

    def astropi_case(self) -> None:
        from gcs_core.convert import astropi as ap
        from gcs_core.convert import convert
        from gcs_core.convert.common import read_named_csv

        src = self.work / "a.csv"
        src.write_bytes(mutate(self.rng, self.astropi_csv))
        if self.rng.random() < 0.005:
            out = self.work / "aout"
            shutil.rmtree(out, ignore_errors=True)
            self.case("astropi", lambda: convert("astropi", src, out, tle=self.tle))
            return

        def read() -> None:
            table = read_named_csv(src, (ap.TIME_COLUMN, *ap.FIELD_COLUMNS))
            ap._times(table)
            B = np.column_stack([table.numbers(c) for c in ap.FIELD_COLUMNS]) * ap.UT_TO_NT
            aux = {ap.AUX_COLUMNS[c]: table.numbers(c) for c in ap.AUX_COLUMNS if c in table.header}
            ap._refuse_absurd(table, B, aux)

        self.case("astropi", read)

    def names_case(self) -> None:
        from gcs_core.io.mission import read_mission_spec
        from gcs_tui.cli import commands as cli
        from gcs_tui.cli.progress import Progress

        text = self.toml.decode()
        for key in ('name = "tiny"', 'name = "TAM1"'):
            hostile = "".join(self.rng.choice(HOSTILE + ["a", "1", "_"]) for _ in range(self.rng.randint(1, 6)))
            text = text.replace(key, f"name = {_toml_string('x' + hostile)}", 1)
        if self.rng.random() < 0.3:
            text += f"{_toml_string(self.rng.choice(HOSTILE) + 'key')} = 1\n"
        (self.tiny / "mission.toml").write_text(text, encoding="utf-8")
        out, err = io.StringIO(), io.StringIO()
        full = self.rng.random() < 0.05
        codes: list[int] = []

        def run() -> None:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                if full:
                    codes.append(cli.main(["--progress", "plain", "import", str(self.tiny)]))
                    return
                prog = Progress(err, mode="plain")
                try:
                    with prog.task(f"reading mission {self.tiny}"):
                        spec = read_mission_spec(self.tiny)
                    cli._out(f"mission {spec.name}: " + ", ".join(f"{s.name} {s.type}" for s in spec.sensors))
                    prog.message(f"fitting {spec.name}")
                except GcsError as e:
                    cli._error(prog, f"error: {e}", 2)

        self.case("names", run)
        shown = out.getvalue() + err.getvalue()
        if RAW.search(shown) or (codes and codes[0] == 4) or err.getvalue().count("\n") > 3:
            self.counts["names"]["unhandled"] += 1
            self.examples.append(f"names: raw control characters or exit 4: {shown!r}")


def _toml_string(s: str) -> str:
    """A TOML basic string holding ``s`` (controls written as \\u escapes)."""
    body = "".join(f"\\u{ord(c):04x}" if (ord(c) < 0x20 or ord(c) == 0x7F or c in '"\\') else c for c in s)
    return f'"{body}"'


def _tiny_mission(d: Path) -> Path:
    (d / "telemetry").mkdir(parents=True)
    (d / "mission.toml").write_text(
        '[mission]\nname = "tiny"\nepoch = "2024-03-20T06:00:00Z"\nattitude_mode = "inertial"\n\n'
        '[ephemeris]\nfile = "ephemeris.csv"\n\n[[sensor]]\nname = "TAM1"\ntype = "magnetometer"\n'
        'telemetry = "telemetry/TAM1.csv"\nalignment_deg = [0.0, 0.0, 0.0]\nnoise = 25.0\nbias = [0.0, 0.0, 0.0]\n'
    )
    (d / "ephemeris.csv").write_text(
        "t,rx,ry,rz,vx,vy,vz,sx,sy,sz\n0,7000,0,0,0,7.5,0,1.496e8,0,0\n"
        "60,7000,450,0,-0.5,7.5,0,1.496e8,1,0\n120,6990,900,0,-1,7.4,0,1.496e8,2,0\n"
    )
    (d / "telemetry" / "TAM1.csv").write_text("t,bx,by,bz\n1,100,200,300\n2,101,201,301\n3,102,202,302\n")
    return d


def _craft_broad(src: Path, rng: random.Random) -> None:
    """One crafted type or shape variant of a valid trial."""
    names = ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "opt_pos", "movement")
    with h5py.File(src, "r+") as f:
        name = rng.choice(names)
        kind = rng.randrange(9)
        shape = f[name].shape
        if kind < 7:
            del f[name]
        if kind == 0:
            f.create_group(name)
        elif kind == 1:
            f[name] = np.full(shape, b"x")
        elif kind == 2:
            f[name] = 1.0
        elif kind == 3:
            f[name] = np.zeros((shape[0], rng.randint(0, 6)))
        elif kind == 4:
            f[name] = np.zeros((0,) + shape[1:])
        elif kind == 5:
            f[name] = np.full(shape, rng.choice([np.nan, np.inf, 1e300, -1e300]))
        elif kind == 6:
            f[name] = h5py.SoftLink("/" + rng.choice(names))
        elif kind == 7:
            f.attrs["sampling_rate"] = rng.choice(["fast", np.array([1.0, 2.0]), -5.0, 0.0, np.nan, 1e300, 1e-300])
        else:
            del f.attrs["sampling_rate"]


def run_untrusted(cases: int, seed: int, work: Path) -> tuple[dict[str, dict[str, int]], list[str]]:
    """``cases`` cases of each reader; returns the counts per reader and the unhandled cases."""
    fz = Fuzzer(work, seed)
    step = {
        "config": fz.config_case,
        "mission.toml": fz.toml_case,
        "scds": fz.scds_case,
        "broad": fz.broad_case,
        "astropi": fz.astropi_case,
        "names": fz.names_case,
    }
    for reader in READERS:
        for _ in range(cases):
            step[reader]()
    return fz.counts, fz.examples
