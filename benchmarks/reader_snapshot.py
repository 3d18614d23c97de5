"""Before/after snapshot of mission.toml's reader and the two converters (a refactoring of
them must change nothing, bit for bit).

Run the same checkout's script against the code before and after, then compare::

    PYTHONPATH=BEFORE_TREE python benchmarks/reader_snapshot.py save before.pkl
    PYTHONPATH=$PWD        python benchmarks/reader_snapshot.py save after.pkl
    python benchmarks/reader_snapshot.py compare before.pkl after.pkl

(from the repository root; ``save`` works in a fixed scratch folder, so the paths the
outcomes name are the same in both runs). ``compare`` prints the cases and those that
differ; exit 1 when any does.

Missions: every mission.toml under sample_data/missions and /work/shared/examples, a plan
file made from one, and line mutations of three of them (a line deleted, its value made a
string / a negative number / a list, its key misspelt, a table header renamed), each read
with planning off and on. Recorded: repr of the MissionSpec or the error (type, message,
file, line, column, key), and every log record.
Converters: astropi on the bundled extract (and variants), broad on the tests' simulated
trials (variants); recorded: the report's repr and every output file's bytes.
"""

from __future__ import annotations

import logging
import pickle
import shutil
import sys
import tempfile
from pathlib import Path

sys.path[:0] = ["tests/helpers", "tests/unit", "tests"]

#: the scratch folder (the same for both runs: error messages and reports name paths in it)
W = Path(tempfile.gettempdir()) / "gcs-reader-snapshot"
records: list[logging.LogRecord] = []


class Grab(logging.Handler):
    def emit(self, record):
        records.append(record)


logging.getLogger().addHandler(Grab())
logging.getLogger().setLevel(logging.DEBUG)


def outcome(fn, *args, **kw):
    """repr of ``fn(*args, **kw)`` or of its error, and the engine's log records."""
    records.clear()
    try:
        r = ("OK", repr(fn(*args, **kw)))
    except Exception as e:  # noqa: BLE001 — every outcome is recorded, the refusals too
        r = ("ERR", type(e).__name__, str(e), *(repr(getattr(e, a, None)) for a in ("file", "line", "column", "key")))
    return r, tuple((x.levelname, x.name, x.getMessage()) for x in records if x.name.startswith("gcs_core"))


def missions(out):
    from gcs_core.io.mission import read_mission_spec

    dirs = sorted(Path("sample_data/missions").glob("*/mission.toml")) + sorted(
        Path("/work/shared/examples").glob("*/mission.toml")
    )
    for p in dirs:
        for planning in (False, True):
            out[("mission", str(p), planning)] = outcome(read_mission_spec, p.parent, planning=planning)
    # a plan file: nominal-sunpoint without telemetry and ephemeris, with cadences
    plan = W / "plan" / "plan.toml"
    plan.parent.mkdir(parents=True)
    lines = []
    for ln in Path("sample_data/missions/nominal-sunpoint/mission.toml").read_text().splitlines():
        if (
            ln.startswith("telemetry")
            or ln.startswith("file =")
            or ln in ("[ephemeris]", "[aux]", "[onboard_attitude]")
        ):
            continue
        lines.append(ln)
        if ln.startswith("type ="):
            lines.append("cadence = 60.0")
            lines.append("gaps = [[100.0, 200.0]]")
    plan.write_text("\n".join(lines) + "\n")
    sources = [
        Path("sample_data/missions/nominal-sunpoint"),
        Path("sample_data/missions/spinner-hidden-horizon"),
        Path("sample_data/missions/real-broad-02-slow-rotation"),
        plan.parent,
    ]
    for src in sources:
        mdir = W / "mut" / src.name
        mdir.mkdir(parents=True)
        for item in src.iterdir():
            if item.name not in ("mission.toml", "plan.toml"):
                (mdir / item.name).symlink_to(item.resolve())
        text = (src / "mission.toml" if (src / "mission.toml").exists() else src / "plan.toml").read_text()
        base = text.splitlines()
        variants = [("orig", base)]
        for i, ln in enumerate(base):
            s = ln.strip()
            if not s or s.startswith("#"):
                continue
            variants.append((f"del{i}", base[:i] + base[i + 1 :]))
            if s.startswith("["):
                variants.append((f"hdr{i}", base[:i] + [s.replace("]", "x]", 1)] + base[i + 1 :]))
                continue
            key, _, _ = ln.partition("=")
            for tag, val in (
                ("str", '"x"'),
                ("neg", "-1"),
                ("big", "1e12"),
                ("list", "[1.0, 2.0]"),
                ("list3", "[1, 2, 3]"),
                ("far", "[400.0, 0.0, 0.0]"),
                ("att", '"att"'),
                ("num", '"1bad"'),
                ("hor", '"horizon"'),
                ("pfs", '"plane_field_sun"'),
                ("tam", '"TAM1"'),
            ):
                variants.append((f"{tag}{i}", base[:i] + [f"{key}= {val}"] + base[i + 1 :]))
            variants.append((f"typo{i}", base[:i] + [key.strip() + "x =" + ln.partition("=")[2]] + base[i + 1 :]))
            variants.append((f"dup{i}", base[: i + 1] + [f"extra_{i} = 1"] + base[i + 1 :]))
        for tag, v in variants:
            (mdir / "mission.toml").write_text("\n".join(v) + "\n")
            for planning in (False, True):
                out[("mut", src.name, tag, planning)] = outcome(read_mission_spec, mdir, planning=planning)


def files_of(d: Path):
    if not d.exists():
        return None
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def converters(out):
    import numpy as np
    from test_convert_broad import _trial

    from gcs_core.convert import convert

    data = Path("tests/data/astropi")
    a = W / "astropi"
    a.mkdir(parents=True)
    csv = data / "astropi_extract.csv"
    tle = data / "iss-2022-01-31.tle"
    lines = csv.read_text().splitlines()
    header = lines[0].split(",")
    # variants: as is; without its LICENCE/SOURCE beside; without aux columns; stale TLE epoch
    bare = a / "bare" / "x.csv"
    bare.parent.mkdir()
    shutil.copyfile(csv, bare)
    keep = [j for j, c in enumerate(header) if c.strip() not in ("Temperature", "Humidity", "Pressure", "C")]
    noaux = a / "noaux" / "x.csv"
    noaux.parent.mkdir()
    noaux.write_text("\n".join(",".join(ln.split(",")[j] for j in keep) for ln in lines) + "\n")
    late = a / "late" / "x.csv"
    late.parent.mkdir()
    late.write_text("\n".join([lines[0]] + [ln.replace("2022-01-31", "2022-03-31", 1) for ln in lines[1:]]) + "\n")
    short = a / "short" / "x.csv"
    short.parent.mkdir()
    short.write_text("\n".join(lines[:4]) + "\n")
    for tag, src, kw in (
        ("extract", csv, {}),
        ("named", csv, {"name": "iss-x"}),
        ("bare", bare, {}),
        ("noaux", noaux, {}),
        ("late", late, {}),
        ("short", short, {}),
        ("notle", csv, {"tle": None}),
    ):
        o = a / "out" / tag
        kw = {"tle": tle, **kw}
        out[("astropi", tag)] = (outcome(convert, "astropi", src, o, **kw), files_of(o))
    b = W / "broad"
    b.mkdir(parents=True)
    (b / "lic").mkdir()
    (b / "lic" / "LICENSE").write_text("CC BY 4.0\n")
    trials = {
        "plain": (b / "plain.hdf5", {}),
        "lic": (b / "lic" / "t.hdf5", {}),
        "bus": (b / "bus.hdf5", {"bus": True, "gyro_step": 3e-3}),
        "rate": (b / "rate.hdf5", {"rate": 50.0}),
        "quant": (b / "quant.hdf5", {"gyro_step": 1e-1}),
        "badq": (b / "badq.hdf5", {"bad_quat": True}),
    }
    for p, kw in trials.values():
        _trial(p, **kw)
    for tag, (p, _), ckw in (
        ("plain", trials["plain"], {}),
        ("lic", trials["lic"], {"name": "x"}),
        ("bus", trials["bus"], {}),
        ("rate", trials["rate"], {}),
        ("quant", trials["quant"], {}),
        ("badq", trials["badq"], {}),
        ("span", trials["plain"], {"span": (1.0, 9.0)}),
        ("span-short", trials["plain"], {"span": (1.0, 1.5)}),
        ("span-back", trials["plain"], {"span": (5.0, 1.0)}),
        ("span-rest", trials["plain"], {"span": (6.5, 11.0)}),
        ("span-untracked", trials["plain"], {"span": (0.0, 1.0)}),
    ):
        o = b / "out" / tag
        out[("broad", tag)] = (outcome(convert, "broad", p, o, **ckw), files_of(o))
    # an all-NaN optical reference
    import h5py

    nan = b / "nan.hdf5"
    shutil.copyfile(trials["plain"][0], nan)
    with h5py.File(nan, "r+") as f:
        f["opt_quat"][...] = np.nan
    o = b / "out" / "nan"
    out[("broad", "nan")] = (outcome(convert, "broad", nan, o), files_of(o))
    # a channel constant at rest: the noise floors (magnetometer, optical, gyro)
    for ds in ("imu_mag", "opt_quat", "imu_gyr"):
        flat = b / f"flat_{ds}.hdf5"
        shutil.copyfile(trials["plain"][0], flat)
        with h5py.File(flat, "r+") as f:
            still = ~f["movement"][()].astype(bool)
            v = f[ds][()]
            v[still] = v[np.flatnonzero(still)[20]]
            f[ds][...] = v
        o = b / "out" / f"flat_{ds}"
        out[("broad", f"flat_{ds}")] = (outcome(convert, "broad", flat, o), files_of(o))


def save(path: Path) -> None:
    if W.exists():
        shutil.rmtree(W)
    W.mkdir(parents=True)
    out: dict = {}
    missions(out)
    converters(out)
    with open(path, "wb") as fh:
        pickle.dump(out, fh)
    shutil.rmtree(W)
    ok = sum(1 for k, v in out.items() if (v[0][0] if k[0] in ("astropi", "broad") else v[0])[0] == "OK")
    import gcs_core

    print(f"{len(out)} cases ({ok} read or converted, the rest refused) by {Path(gcs_core.__file__).parent}")


def compare(before: Path, after: Path) -> int:
    with open(before, "rb") as fa, open(after, "rb") as fb:
        a, b = pickle.load(fa), pickle.load(fb)  # our own files, written by save()
    keys = sorted(set(a) | set(b), key=repr)
    bad = [k for k in keys if k not in a or k not in b or a[k] != b[k]]
    for k in bad:
        print("differs:", k)
    print(f"{len(keys)} cases, {len(bad)} differ")
    return 1 if bad else 0


def main() -> int:
    if len(sys.argv) == 3 and sys.argv[1] == "save":
        save(Path(sys.argv[2]))
        return 0
    if len(sys.argv) == 4 and sys.argv[1] == "compare":
        return compare(Path(sys.argv[2]), Path(sys.argv[3]))
    print(__doc__)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
