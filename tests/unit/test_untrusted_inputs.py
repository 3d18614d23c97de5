"""Issue 23: the exit-4 cases where the input is at fault (now exit 2, one line), the sizes
bounded before allocating, and the "smaller" list. Each reproducer of the issue is a test.
"""

from __future__ import annotations

import os
import shutil
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
from repo_paths import ROOT, SAMPLE_MISSIONS, TEST_DATA
from untrusted_cases import broad_trial

from gcs_core import compiled
from gcs_core.config import load_config
from gcs_core.errors import InputError
from gcs_tui.cli import commands as cli

MISSION = SAMPLE_MISSIONS / "nominal-sunpoint"
CONFIG = ROOT / "sample_data" / "configs" / "nominal-sunpoint.toml"
TRADE = ROOT / "sample_data" / "trade" / "smm-tam-bias.toml"
ASTROPI = TEST_DATA / "astropi"


def one_line(capsys, code: int, expected: int = 2) -> str:
    err = capsys.readouterr().err.strip()
    assert code == expected, err
    assert err.count("\n") == 0 and "Traceback" not in err and "internal error" not in err, err
    assert "RuntimeWarning" not in err, err
    return err


@pytest.fixture
def mission(tmp_path) -> Path:
    m = tmp_path / "mission"
    shutil.copytree(MISSION, m)
    return m


def config(tmp_path, mission: Path, edit=lambda s: s) -> Path:
    text = CONFIG.read_text().replace('"../missions/nominal-sunpoint"', f'"{mission}"')
    p = tmp_path / "c.toml"
    p.write_text(edit(text), encoding="utf-8")
    return p


# ------------------------------------------------------------------ big integers, BOM
@pytest.mark.parametrize("digits", [400, 5000])
def test_huge_integers_in_a_config_and_mission_toml(tmp_path, mission, capsys, digits):
    big = "9" * digits
    cfg = config(tmp_path, mission, lambda s: s.replace("attitude_sigma_deg = 1.0", f"attitude_sigma_deg = {big}"))
    assert "state.attitude_sigma_deg" in one_line(capsys, cli.main(["-q", "batch", str(cfg)])) or digits > 4300
    toml = mission / "mission.toml"
    toml.write_text(toml.read_text().replace("noise = 25.0", f"noise = {big}", 1))
    err = one_line(capsys, cli.main(["-q", "import", str(mission)]))
    assert "digits" in err and "mission.toml" in err


def test_a_utf8_bom_in_a_config_is_accepted(tmp_path, mission):
    cfg = config(tmp_path, mission)
    plain = load_config(cfg)
    cfg.write_bytes(b"\xef\xbb\xbf" + cfg.read_bytes())
    assert load_config(cfg) == plain
    toml = mission / "mission.toml"
    toml.write_bytes(b"\xef\xbb\xbf" + toml.read_bytes())
    from gcs_core.io.mission import read_mission_spec

    assert read_mission_spec(mission).name == "nominal-sunpoint"


# ------------------------------------------------------------------ unreadable inputs
def test_a_mission_directory_that_cannot_be_listed(mission, monkeypatch, capsys):
    if os.geteuid() == 0:  # root ignores chmod 000: refuse as the system would
        from gcs_core import inputs

        real = inputs.os.listdir

        def listdir(p):
            if Path(p) == mission:
                raise PermissionError(13, "Permission denied")
            return real(p)

        monkeypatch.setattr(inputs.os, "listdir", listdir)
        code = cli.main(["-q", "import", str(mission)])
    else:
        mission.chmod(0)
        try:
            code = cli.main(["-q", "import", str(mission)])
        finally:
            mission.chmod(0o755)
    assert "cannot be read (Permission denied)" in one_line(capsys, code)


def test_fifos_devices_and_link_loops_are_named(tmp_path, mission, capsys):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    for target, words in ((fifo, "FIFO"), (Path("/dev/zero"), "device"), (loop, "loop of symbolic links")):
        for argv in (["import", str(target)], ["batch", str(target)], ["convert", "broad", str(target), "--out", "x"]):
            assert words in one_line(capsys, cli.main(["-q", *argv]))
    tam = mission / "telemetry" / "TAM1.csv"
    tam.unlink()
    os.mkfifo(tam)  # a telemetry file that would block a reader forever
    assert "FIFO" in one_line(capsys, cli.main(["-q", "import", str(mission)]))


# ------------------------------------------------------------------ corrupt BROAD files
def test_random_corruptions_of_a_broad_file_are_exit_2(tmp_path, capsys):
    good = broad_trial(tmp_path / "good.hdf5").read_bytes()
    rng = np.random.default_rng(23)
    bad = tmp_path / "bad.hdf5"
    for k in range(24):
        data = bytearray(good)
        for pos in rng.integers(0, len(data), size=int(rng.integers(1, 20))):
            data[int(pos)] = int(rng.integers(0, 256))
        bad.write_bytes(bytes(data))
        code = cli.main(["-q", "convert", "broad", str(bad), "--out", str(tmp_path / f"o{k}")])
        err = capsys.readouterr().err
        assert code in (0, 2) and "internal error" not in err and err.count("\n") <= 1, err


@pytest.mark.parametrize(
    "craft",
    ["group", "strings", "scalar", "wrong_columns", "empty", "rate_text", "rate_array", "compound"],
)
def test_crafted_broad_types_and_shapes_are_exit_2(tmp_path, capsys, craft):
    src = broad_trial(tmp_path / "t.hdf5")
    with h5py.File(src, "r+") as f:
        if craft == "group":
            del f["imu_gyr"]
            f.create_group("imu_gyr")
        elif craft == "strings":
            del f["imu_mag"]
            f["imu_mag"] = np.array([[b"a", b"b", b"c"]] * 5)
        elif craft == "scalar":
            del f["imu_acc"]
            f["imu_acc"] = 3.0
        elif craft == "wrong_columns":
            del f["opt_pos"]
            f["opt_pos"] = np.zeros((400, 2))
        elif craft == "empty":
            for name in ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "opt_pos", "movement"):
                shape = f[name].shape
                del f[name]
                f[name] = np.zeros((0,) + shape[1:])
        elif craft == "rate_text":
            f.attrs["sampling_rate"] = "fast"
        elif craft == "rate_array":
            f.attrs["sampling_rate"] = np.array([50.0, 60.0])
        elif craft == "compound":
            del f["movement"]
            f["movement"] = np.zeros(400, dtype=[("a", "i4"), ("b", "f8")])
    one_line(capsys, cli.main(["-q", "convert", "broad", str(src), "--out", str(tmp_path / "m")]))


# ------------------------------------------------------------------ numba's cache
def test_numba_cache_falls_back_when_nothing_can_be_written(monkeypatch, tmp_path):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(compiled, "_writable", lambda folder: False)
    assert compiled.cache_choice() == (False, None)  # nowhere at all: compile without caching
    writable = {str(tmp_path / "t" / f"gcs-numba-{os.getuid()}")}
    monkeypatch.setattr(compiled, "_writable", lambda folder: folder in writable)
    monkeypatch.setattr(compiled.tempfile, "gettempdir", lambda: str(tmp_path / "t"))
    assert compiled.cache_choice() == (True, str(tmp_path / "t" / f"gcs-numba-{os.getuid()}"))
    os.chmod(tmp_path / "t" / f"gcs-numba-{os.getuid()}", 0o777)  # another user could plant code
    assert compiled.cache_choice() == (False, None)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert compiled.cache_choice() == (True, None)


def test_read_only_install_with_unwritable_home_runs(tmp_path):
    """A subprocess with HOME unwritable and the install's own __pycache__ refused."""
    import subprocess
    import sys

    script = (
        "import os, tempfile\n"
        "real = tempfile.mkstemp\n"
        "def mkstemp(*a, dir=None, **k):\n"
        "    if dir and 'gcs-numba-' not in dir: raise PermissionError(13, 'Permission denied')\n"
        "    return real(*a, dir=dir, **k)\n"
        "tempfile.mkstemp = mkstemp\n"
        "from gcs_core import compiled\n"
        "print(compiled.CACHE, os.environ.get('NUMBA_CACHE_DIR', ''))\n"
    )
    env = dict(os.environ, PYTHONPATH=str(ROOT), HOME="/nonexistent/home", TMPDIR=str(tmp_path))
    env.pop("NUMBA_CACHE_DIR", None)
    env.pop("XDG_CACHE_HOME", None)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", str(tmp_path / f"gcs-numba-{os.getuid()}")]


# ------------------------------------------------------------------ sizes
def test_sizes_are_bounded_before_allocating(tmp_path, mission, capsys):
    cfg = config(tmp_path, mission, lambda s: s.replace("step = 60.0", "step = 1e-6"))
    err = one_line(capsys, cli.main(["-q", "predict", str(cfg)]))
    assert "prediction.step" in err and "at most 1000000" in err
    for runs in ("0", "1000000000000"):
        err = one_line(capsys, cli.main(["-q", "montecarlo", str(TRADE), "--runs", runs]))
        assert "--runs" in err and "1 to 100000" in err
    err = one_line(
        capsys, cli.main(["-q", "trade", str(TRADE), "--vary", "span_min=1e9", "--output", str(tmp_path / "x.h5")])
    )
    assert "trade.vary.span_min" in err and "limit" in err
    from gcs_core.estimators.whole_span.knots import make_grid

    with pytest.raises(InputError, match="at most 2000000") as info:
        make_grid(0.0, 1e6, 1e-6, 1e-6, 1e-8)  # a microsecond spacing over 12 days
    assert info.value.key == "whole_span.knots"


# ------------------------------------------------------------------ the smaller list
def test_every_model_off_is_a_config_error(tmp_path, mission, capsys):
    def off(s):
        for name in ("TAM1", "IRU", "FHST1", "FHST2", "FSS1", "CSS1"):
            s = s.replace(f'\n{name} = "', f'\n{name} = "off" #"')
        return s.split("[state.elements")[0] + "\n[filter]\n" + s.split("[filter]")[1]

    err = one_line(capsys, cli.main(["-q", "batch", str(config(tmp_path, mission, off))]))
    assert "key 'models': every sensor's model is off" in err


@pytest.mark.parametrize("edit", ["value = 1e300", "sigma = 1e-300", "sigma = 1e300"])
def test_absurd_a_priori_values_are_exit_2_without_warnings(tmp_path, mission, capsys, edit):
    def change(s):
        return (
            s.replace("sigma = inf", edit, 1) if edit.startswith("sigma") else s.replace("value = 0.0 ", edit + " ", 1)
        )

    err = one_line(capsys, cli.main(["-q", "batch", str(config(tmp_path, mission, change))]))
    assert 'state.elements."CSS1.b_alpha"' in err


def _tle_years_off(tmp_path, years: int) -> Path:
    lines = (ASTROPI / "iss-2022-01-31.tle").read_text().splitlines()
    line1 = lines[1][:18] + f"{22 - years:02d}" + lines[1][20:68]
    digits = sum(int(c) for c in line1 if c.isdigit()) + line1.count("-")
    p = tmp_path / "old.tle"
    p.write_text("\n".join([lines[0], line1 + str(digits % 10), lines[2]]) + "\n")
    return p


@pytest.mark.parametrize("years", [1, 13])
def test_a_tle_years_from_the_data_warns(tmp_path, capsys, years):
    """One year off converts with the warning; thirteen years off warns, then SGP4 itself
    gives up (the station "decayed"): one line, exit 2."""
    tle = _tle_years_off(tmp_path, years)
    argv = ["convert", "astropi", str(ASTROPI / "astropi_extract.csv"), "--tle", str(tle), "--out", str(tmp_path / "m")]
    code = cli.main(argv)
    captured = capsys.readouterr()
    assert "gcs: warning: the data lie" in captured.err and "days from the epoch of old.tle" in captured.err
    if years == 1:
        assert code == 0 and "days from the epoch of old.tle" in captured.out
    else:
        assert code == 2 and "internal error" not in captured.err


def test_an_absurd_astropi_value_is_refused(tmp_path, capsys):
    lines = (ASTROPI / "astropi_extract.csv").read_text().splitlines()
    header = lines[0].split(",")
    j = header.index("MagX")
    row = lines[5].split(",")
    row[j] = "1e300"
    lines[5] = ",".join(row)
    csv = tmp_path / "a.csv"
    csv.write_text("\n".join(lines) + "\n")
    argv = [
        "-q",
        "convert",
        "astropi",
        str(csv),
        "--tle",
        str(ASTROPI / "iss-2022-01-31.tle"),
        "--out",
        str(tmp_path / "m"),
    ]
    err = one_line(capsys, cli.main(argv))
    assert "a.csv:6:" in err and "MagX" in err and "exceeds" in err


def test_trade_vary_text_for_a_number_is_exit_2(tmp_path, capsys):
    err = one_line(
        capsys, cli.main(["-q", "trade", str(TRADE), "--vary", "span_min=abc", "--output", str(tmp_path / "t.h5")])
    )
    assert "trade.vary.span_min" in err and "must be a number" in err


def test_the_dask_dashboard_listens_on_the_loopback_only(monkeypatch):
    distributed = pytest.importorskip("distributed")
    seen = {}

    class Fake:
        def __init__(self, **kw):
            seen.update(kw)
            raise RuntimeError("stop here")

    import dask.distributed  # imported first: it copies distributed's names when first imported

    monkeypatch.setattr(distributed, "LocalCluster", Fake)
    monkeypatch.setattr(dask.distributed, "LocalCluster", Fake)
    from gcs_core.trade import engine

    with pytest.raises(RuntimeError, match="stop here"):
        engine.connect(1, None)
    assert seen["host"] == "127.0.0.1" and seen["dashboard_address"].startswith("127.0.0.1:")


def test_numpy_warnings_never_reach_stderr(monkeypatch, capsys):
    def noisy(args, prog):
        np.nanmax(np.array([np.nan]))  # "All-NaN slice encountered"
        with np.errstate(over="warn"):
            np.float64(1e300) * np.float64(1e300)
        return 0

    monkeypatch.setattr(cli, "cmd_effects", noisy)
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        code = cli.main(["effects"])
    err = capsys.readouterr().err
    assert code == 0 and "RuntimeWarning" not in err and "All-NaN" not in err, err


def test_an_input_error_stays_one_line(tmp_path):
    with pytest.raises(InputError) as info:
        load_config(tmp_path / "absent.toml")
    assert "\n" not in str(info.value)
