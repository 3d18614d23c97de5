"""Fuzz the mission readers: >= 10,000 seeded mutations of valid files.

Each case mutates a valid CSV table, a valid mission.toml or a whole copied mission
directory (a CSV of it) and reads it. The reader must return its object or raise one
``InputError`` whose message is one line; anything else counts as *unhandled*.

With ``--suite untrusted`` (or ``all``, the default) it also fuzzes the readers of issue 23,
``N`` cases each (:mod:`_fuzz_untrusted`): the analysis config, mission.toml, SCDS files
(damaged bytes, links, datasets for groups, long version numbers), the BROAD and Astro Pi
converters (random corruption, crafted types and shapes) and names holding control
characters (nothing a terminal would obey may be printed). It prints per reader the
outcomes, accepted, refused (one-line ``GcsError``: exit 2) and unhandled (exit 4).

Run: ``python benchmarks/fuzz_readers.py [--cases N] [--seed S] [--suite all|readers|untrusted]``;
exits 1 if any case was unhandled. Prints the counts and the first few unhandled cases.
"""

from __future__ import annotations

import argparse
import logging
import random
import shutil
import sys
import tempfile
import time
import traceback
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from gcs_core.errors import InputError
from gcs_core.io.csvio import read_table
from gcs_core.io.importer import load_mission
from gcs_core.io.mission import read_mission_spec

EXAMPLE = REPO.parent / "shared" / "examples" / "sunpoint-nominal"

CSV = (
    b"# simulated magnetometer\n"
    b"t,bx,by,bz,temp\n"
    b"0.000,-27.329,1243.023,29400.574,20\n"
    b"1.000,20.965,1157.964,29340.706,20.1\n"
    b"2.000,-46.982,1207.348,29357.913,20.2\n"
    b"2.000,-46.982,1207.348,29357.913,20.2\n"
    b"3.5,,1140.691,29339.207,20.3\n"
    b"4.0,-1.1e2,1.14e3,2.9339207e4,nan\n"
)

TOML = b"""# a small mission
[mission]
name = "fuzz"
epoch = "2024-03-20T06:00:00Z"
attitude_mode = "spinning"
spin_axis_guess_deg = [303.5, -25.5]

[ephemeris]
file = "ephemeris.csv"

[onboard_attitude]
file = "onboard.csv"

[[sensor]]
name = "TAM1"
type = "magnetometer"
telemetry = "telemetry/TAM1.csv"
alignment_deg = [0.0, 0.0, 0.0]
noise = 25.0
bias = [0.0, 0.0, 0.0]

[[sensor]]
name = "PFS"
type = "plane_field_sun"
telemetry = "telemetry/PFS.csv"
tilt_deg = 1.0
bias = 0.0
noise = 0.001

[[sensor]]
name = "HS"
type = "horizon"
telemetry = "telemetry/HS.csv"
gamma_deg = 60.0
phi_h_deg = 10.0
horizon_height_km = 40.0
noise = 0.001
sun_sensor = "PFS"
observable = "width_midscan"

[[sensor]]
name = "CSS1"
type = "coarse_sun"
telemetry = "telemetry/CSS1.csv"
fov_deg = 60.0
noise = 0.577
scale = [4.36e-03, 4.36e-03]
bias = [0.0, 0.0]
"""

TOKENS = [
    b"",
    b",",
    b",,",
    b"nan",
    b"NaN",
    b"inf",
    b"-inf",
    b"1e400",
    b"#",
    b"\n",
    b"\r\n",
    b"\x00",
    b"\xff\xfe",
    "\ufeff".encode(),
    b"t",
    b"1",
    b"-0",
    b"1e-320",
    b"abc",
    b" ",
    b'"',
    b"0x10",
    b"1_0",
    "\u0661".encode(),
    b"9" * 400,
    b"-1e308",
    b"[",
    b"]",
    b"=",
    b"[[sensor]]",
    b"[mission]",
    b"'",
    b"\\",
    b"{",
    b"}",
    b"1979-05-27T07:32:00Z",
]
VALUES = [
    b'""',
    b'"x"',
    b"-1",
    b"0",
    b"1e999",
    b"inf",
    b"nan",
    b"-inf",
    b"true",
    b"[]",
    b"[1, 2]",
    b"[1, 2, 3]",
    b"[1, 2, 3, 4]",
    b"[[1]]",
    b"{a = 1}",
    b"1979-05-27T07:32:00Z",
    b"1979-05-27",
    b"07:32:00",
    b'"/"',
    b'"telemetry"',
    b'"horizon"',
    b'"spinning"',
    b'"PFS"',
    b'"HS"',
    b'"TAM1"',
    b'"9999-12-31T23:59:59.9999999-23:59"',
    b"[0.0, 1e300]",
    b'"0001-01-01T00:00:00+23:59"',
    b"'''x'''",
    b'"a\\u0000b"',
    b'"sun_pointing"',
    b'"../mission.toml"',
    b'"' + b"x" * 300 + b'"',
]


def mutate(rng: random.Random, data: bytes, n_ops: int) -> bytes:
    for _ in range(n_ops):
        kind = rng.choice(
            ("insert", "delete", "flip", "dupline", "swaplines", "delline", "setvalue", "setvalue", "truncate")
        )
        p = rng.randint(0, len(data))
        if kind == "insert":
            tok = rng.choice(TOKENS) if rng.random() < 0.8 else rng.randbytes(rng.randint(1, 4))
            data = data[:p] + tok + data[p:]
        elif kind == "delete":
            data = data[:p] + data[p + rng.randint(1, 40) :]
        elif kind == "flip" and data:
            p = min(p, len(data) - 1)
            data = data[:p] + bytes([rng.randrange(256)]) + data[p + 1 :]
        elif kind == "truncate":
            data = data[:p]
        else:
            lines = data.split(b"\n")
            i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
            if kind == "dupline":
                lines.insert(i, lines[i])
            elif kind == "swaplines":
                lines[i], lines[j] = lines[j], lines[i]
            elif kind == "delline":
                del lines[i]
            elif kind == "setvalue":
                eq = [k for k, line in enumerate(lines) if b"=" in line and b"," not in line]
                if eq:
                    k = rng.choice(eq)
                    lines[k] = lines[k].split(b"=", 1)[0] + b"= " + rng.choice(VALUES)
                else:  # a CSV: replace one field
                    fields = lines[i].split(b",")
                    fields[rng.randrange(len(fields))] = rng.choice(TOKENS)
                    lines[i] = b",".join(fields)
            data = b"\n".join(lines)
    return data


def make_spinner(root: Path) -> Path:
    d = root / "spinner"
    (d / "telemetry").mkdir(parents=True)
    (d / "ephemeris.csv").write_text(
        "t,rx,ry,rz,vx,vy,vz,sx,sy,sz\n0,7000,0,0,0,7.5,0,1.496e8,0,0\n60,7000,450,0,-0.5,7.5,0,1.496e8,1,0\n"
    )
    (d / "onboard.csv").write_text("t,q1,q2,q3,q4\n0,0,0,0,1\n")
    (d / "telemetry/TAM1.csv").write_text("t,bx,by,bz\n0,1,2,3\n")
    (d / "telemetry/PFS.csv").write_text("t,beta\n1,1.2\n")
    (d / "telemetry/HS.csv").write_text("t,spin_rate,dt_in,dt_out\n1,0.5,1,2\n")
    (d / "telemetry/CSS1.csv").write_text("t,n_alpha,n_beta\n1,0,0\n")
    (d / "mission.toml").write_bytes(TOML)
    return d


def run(cases: int, seed: int) -> int:
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)  # unknown-key warnings by the thousand
    rng = random.Random(seed)
    work = Path(tempfile.mkdtemp(prefix="gcs-fuzz-"))
    try:
        spinner = make_spinner(work)
        example = None
        if EXAMPLE.is_dir():
            example = work / "example"
            shutil.copytree(EXAMPLE, example, copy_function=shutil.copyfile)
            for p in [example, *example.rglob("*")]:
                p.chmod(0o755 if p.is_dir() else 0o644)
        csv_path = work / "fuzz.csv"
        read_mission_spec(spinner)  # the unmutated inputs are valid
        csv_path.write_bytes(CSV)
        read_table(csv_path, required=("t", "bx", "by", "bz"))
        if example is not None:
            load_mission(example)
        counts = {"accepted": 0, "refused": 0, "unhandled": 0}
        by_target: dict[str, int] = {}
        unhandled: list[str] = []
        start = time.perf_counter()
        for case in range(cases):
            target = rng.choices(("csv", "toml", "mission"), weights=(9, 9, 2))[0]
            if target == "mission" and example is None:
                target = "toml"
            n_ops = rng.randint(1, 6)
            try:
                if target == "csv":
                    csv_path.write_bytes(mutate(rng, CSV, n_ops))
                    read_table(csv_path, required=("t", "bx", "by", "bz"))
                elif target == "toml":
                    (spinner / "mission.toml").write_bytes(mutate(rng, TOML, n_ops))
                    read_mission_spec(spinner)
                else:
                    victim = rng.choice(
                        [
                            "telemetry/TAM1.csv",
                            "telemetry/FHST1.csv",
                            "ephemeris.csv",
                            "onboard_attitude.csv",
                            "aux.csv",
                        ]
                    )
                    original = (EXAMPLE / victim).read_bytes()
                    (example / victim).write_bytes(mutate(rng, original, n_ops))
                    try:
                        load_mission(example)
                    finally:
                        (example / victim).write_bytes(original)
                counts["accepted"] += 1
            except InputError as err:
                if "\n" in str(err):
                    counts["unhandled"] += 1
                    unhandled.append(f"case {case} ({target}): multi-line message {str(err)!r}")
                else:
                    counts["refused"] += 1
            except Exception:  # noqa: BLE001 — any other exception is what this fuzzer counts
                counts["unhandled"] += 1
                unhandled.append(f"case {case} ({target}):\n" + traceback.format_exc(limit=4))
            by_target[target] = by_target.get(target, 0) + 1
        elapsed = time.perf_counter() - start
    finally:
        shutil.rmtree(work, ignore_errors=True)
        logging.disable(previous)
    print(
        f"fuzz_readers: {cases} cases (seed {seed}) in {elapsed:.1f} s: "
        + ", ".join(f"{k} {v}" for k, v in sorted(by_target.items()))
    )
    print(
        f"  accepted {counts['accepted']}, refused with InputError {counts['refused']}, "
        f"unhandled exceptions {counts['unhandled']}"
    )
    for text in unhandled[:5]:
        print(text)
    return counts["unhandled"]


def run_untrusted(cases: int, seed: int) -> int:
    """The issue-23 readers (``benchmarks/_fuzz_untrusted.py``), ``cases`` cases each;
    prints one line per reader and returns the unhandled (exit-4) count."""
    import warnings

    from _fuzz_untrusted import READERS
    from _fuzz_untrusted import run_untrusted as fuzz

    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)
    work = Path(tempfile.mkdtemp(prefix="gcs-fuzz-untrusted-"))
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numpy's overflow warnings on crafted values (the CLI logs them)
            counts, examples = fuzz(cases, seed, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
        logging.disable(previous)
    elapsed = time.perf_counter() - start
    print(f"fuzz_readers --untrusted: {cases} cases per reader (seed {seed}) in {elapsed:.1f} s")
    print(f"  {'reader':14s} {'outcomes':>9s} {'accepted':>9s} {'refused':>9s} {'unhandled':>9s} {'exit 4':>7s}")
    total = 0
    for reader in READERS:
        c = counts[reader]
        n = sum(c.values())
        total += c["unhandled"]
        print(f"  {reader:14s} {n:9d} {c['accepted']:9d} {c['refused']:9d} {c['unhandled']:9d} {c['unhandled']:7d}")
    for text in examples[:5]:
        print(text)
    return total


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=12_000)
    parser.add_argument("--seed", type=int, default=20240320)
    parser.add_argument(
        "--suite",
        choices=("all", "readers", "untrusted"),
        default="all",
        help="the CSV/mission readers, the issue-23 readers (config, mission.toml, SCDS, converters, names), or both",
    )
    args = parser.parse_args()
    if args.cases < 10_000:
        print("note: fewer than the 10,000 cases the benchmark promises")
    bad = 0
    if args.suite in ("all", "readers"):
        bad += run(args.cases, args.seed)
    if args.suite in ("all", "untrusted"):
        bad += run_untrusted(args.cases, args.seed)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
