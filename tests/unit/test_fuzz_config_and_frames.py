"""Property tests (hypothesis, derandomized): the config loader and the rotation functions.

(a) The analysis-config loader (gcs_core.config) on random TOML-ish text, random bytes and
    random mutations of the documented example config: it returns a config or raises
    ConfigError/InputError with a one-line message, never anything else; a config it
    accepts survives save → load unchanged.
(b) gcs_core.frames.rotations (seed §4.1.2, Eq 4-4..4-11; ICD §2): DCM ↔ quaternion ↔
    Euler 1-2-3 ↔ rotation vector round trips, orthonormality, and quaternion products that
    agree with matrix products (Eq 4-10) and associate.

Every run is derandomized (the same examples each time) with no example database, and
each property stops at a modest number of examples to keep the file fast.
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import tomli_w
from config_example import example_config_text
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcs_core import config as C
from gcs_core import config_schema as S
from gcs_core.errors import ConfigError, InputError
from gcs_core.frames import rotations as R

FUZZ = settings(
    max_examples=250, derandomize=True, database=None, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
FRAMES = settings(max_examples=200, derandomize=True, database=None, deadline=None)

# --- named tolerances -------------------------------------------------------------------
#: round-off on unit-magnitude matrix and quaternion elements after a few operations
round_off = 1e-13
#: dcm_to_euler123 treats |cos θ| < 1e-12 as gimbal lock and sets roll to zero; the
#: rebuilt matrix is then off by about that much
gimbal_lock_round_off = 1e-12
one_arcsecond = math.radians(1.0 / 3600.0)


# =========================================================================== (a) config
def _example_text() -> str:
    """The documented example config: gcs_core/config.py's docstring and the planning
    tables of gcs_core/trade/__init__.py's."""
    return example_config_text()


EXAMPLE = C.parse_toml(_example_text())


def _accepts_or_refuses(load) -> S.AnalysisConfig | None:
    try:
        return load()
    except (ConfigError, InputError) as err:
        text = str(err)
        assert text and "\n" not in text, repr(text)
        return None


def _round_trips(cfg: S.AnalysisConfig) -> None:
    """An accepted config written and read back is the same config."""
    again = C.config_from_dict(C.parse_toml(tomli_w.dumps(S.to_dict(cfg))), path=cfg.path)
    # the planning tables are kept raw (checked by the trade study) and may hold nan, which
    # is equal to itself only through its text
    assert again == cfg or _text(again) == _text(cfg)


def _text(cfg: S.AnalysisConfig) -> str:
    return json.dumps(S.to_dict(cfg), sort_keys=True, default=str)


#: per table: lines that belong there (good and bad values), and a few that do not
_LINES = {
    "[physics]": [
        "stellar_aberration = false",
        "sun_parallax = 1",
        'field_model = "dipole"',
        'field_model = "wmm"',
        "solar_aberration = true",
    ],
    "[models]": ['TAM1 = "magnetometer"', 'IRU = "off"', "CSS1 = 7", 'FSS1 = "gyro"'],
    "[state]": [
        'effects = ["TAM1.alignment"]',
        "effects = [1, 2]",
        'exclude = "TAM1.bias"',
        'exclude = ["IRU.bias"]',
        "attitude_sigma_deg = -1",
        "attitude_sigma_deg = 2.0",
        "elements = 5",
    ],
    '[state.elements."TAM1.bias_x"]': [
        'role = "held"',
        'role = "bogus"',
        "value = nan",
        "value = 3",
        "sigma = inf",
        "sigma = 0",
        "sigma = 20.0",
    ],
    "[filter]": [
        "block_seconds = 1e400",
        "block_seconds = 60",
        "edit_k = 0",
        "max_iterations = 2.5",
        "max_iterations = 5",
    ],
    "[diagnosis]": ["significance = 0.7", "significance = 0.01", "holdout_fraction = 0.1"],
    "[prediction]": [
        "start = 0.0",
        "end = -5.0",
        "end = 600.0",
        "step = 10",
        "gaps = [[1, 2], [3]]",
        'gaps = [["a", "b"]]',
        "gaps = [[1.0, 2.0]]",
        "maneuvers = [1]",
    ],
    "[[prediction.maneuvers]]": [
        "start = 0",
        'axis = "yaw"',
        'axis = "up"',
        "duration = 60",
        "rate_deg_s = 0.1",
        "rate_deg_s = 1e9",
    ],
    "[verification]": ["requirement_deg = 0.01", "requirement_deg = -1"],
    "[unknown]": ["x = 1"],
}
_STRAY = [
    "method = 3",
    'name = "x"',
    "when = 1979-05-27T07:32:00Z",
    "x = {a = 1}",
    "a.b.c = [[[[1]]]]",
    "= 1",
    "[",
    '"',
    "'''",
    "physics = 3",
    "state = []",
    "mission = 5",
    "[analysis]",
]
_SECTION = st.sampled_from(sorted(_LINES)).flatmap(
    lambda head: st.lists(
        st.sampled_from(_LINES[head] + _STRAY[:1]), max_size=5, unique_by=lambda line: line.split("=")[0].strip()
    ).map(lambda lines: "\n".join([head] + lines))
)


@FUZZ
@given(
    st.booleans(),
    st.lists(_SECTION, max_size=6, unique_by=lambda sec: sec.split("\n")[0]),
    st.lists(st.sampled_from(_STRAY), max_size=1),
    st.text(max_size=6),
)
def test_config_loader_on_tomlish_text(with_analysis, sections, stray, noise):
    head = '[analysis]\nmission = "m"\nmethod = "kalman"\n' if with_analysis else ""
    text = head + "\n".join(sections + stray) + "\n" + (noise if not with_analysis else "")
    cfg = _accepts_or_refuses(lambda: C.config_from_dict(C.parse_toml(text), path=Path("/fuzz/a.toml")))
    if cfg is not None:
        _round_trips(cfg)


@settings(max_examples=60, derandomize=True, database=None, deadline=None)
@given(st.binary(max_size=200))
def test_config_loader_on_random_bytes(data):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.toml"
        path.write_bytes(b'[analysis]\nmission = "m"\n' + data)
        _accepts_or_refuses(lambda: C.load_config(path))


_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**6), 10**6)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8)
    | st.sampled_from(["batch", "kalman", "igrf", "yaw", "held", "off", "TAM1.scale"]),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=6,
)


def _paths(d, prefix=()):
    """Every path into a nested dict/list (the places a mutation may hit)."""
    yield prefix
    if isinstance(d, dict):
        for k, v in d.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield from _paths(v, prefix + (i,))


def _without_none(v):
    """TOML has no null: drop None as tomllib could never return it."""
    if isinstance(v, dict):
        return {k: _without_none(x) for k, x in v.items() if x is not None}
    if isinstance(v, list):
        return [_without_none(x) for x in v if x is not None]
    return v


@FUZZ
@given(st.data())
def test_config_loader_on_mutated_example(data):
    import copy

    doc = copy.deepcopy(EXAMPLE)
    for _ in range(data.draw(st.integers(1, 3))):
        paths = [p for p in _paths(doc) if p]
        where = data.draw(st.sampled_from(paths))
        parent = doc
        for k in where[:-1]:
            parent = parent[k]
        action = data.draw(st.sampled_from(["replace", "delete", "add"]))
        if action == "delete":
            del parent[where[-1]]
        elif action == "replace":
            value = _without_none(data.draw(_VALUES))
            if value is None:  # TOML has no null: a key set to nothing is absent
                del parent[where[-1]]
            else:
                parent[where[-1]] = value
        else:
            value = _without_none(data.draw(_VALUES))
            if value is None:
                continue
            if isinstance(parent, dict):
                parent[data.draw(st.text(min_size=1, max_size=8))] = value
            else:
                parent.append(value)
    cfg = _accepts_or_refuses(lambda: C.config_from_dict(doc, path=Path("/fuzz/a.toml")))
    if cfg is not None:
        _round_trips(cfg)


# =========================================================================== (b) frames
_unit = st.floats(-1.0, 1.0, allow_nan=False)
_quats = (
    st.tuples(_unit, _unit, _unit, _unit)
    .filter(lambda q: sum(x * x for x in q) > 1e-6)
    .map(lambda q: np.asarray(q) / np.linalg.norm(q))
)
_angle = st.floats(-math.pi, math.pi, allow_nan=False)


def _same_rotation(qa, qb) -> float:
    """Distance between quaternions up to sign (q and −q are one rotation)."""
    return float(min(np.abs(qa - qb).max(), np.abs(qa + qb).max()))


@FRAMES
@given(_quats)
def test_quat_dcm_round_trip_is_plus_or_minus_q(q):
    """Eq 4-8 then Eq 4-9 (Shepperd's branch): q comes back, up to sign."""
    assert _same_rotation(R.quat_from_dcm(R.quat_to_dcm(q)), q) < round_off


@FRAMES
@given(_quats)
def test_dcm_of_a_unit_quaternion_is_orthonormal(q):
    Cm = R.quat_to_dcm(q)
    np.testing.assert_allclose(Cm @ Cm.T, np.eye(3), atol=round_off)
    assert abs(np.linalg.det(Cm) - 1.0) < round_off


@FRAMES
@given(_angle, st.floats(-math.pi / 2 + 1e-6, math.pi / 2 - 1e-6), _angle)
def test_euler123_round_trip_away_from_gimbal_lock(roll, pitch, yaw):
    """Eq 4-4 then Eq 4-5: the angles come back (roll and yaw modulo 2π). Their error
    grows as 1/cos θ, the conditioning of Eq 4-5 near the lock."""
    r, p, y = R.dcm_to_euler123(R.euler123_to_dcm(roll, pitch, yaw))
    tol = round_off / math.cos(pitch)
    wrap = lambda a: (a + math.pi) % (2 * math.pi) - math.pi
    assert abs(p - pitch) < round_off
    assert abs(wrap(r - roll)) < tol and abs(wrap(y - yaw)) < tol


@FRAMES
@given(_angle, st.sampled_from([1.0, -1.0]), st.floats(0.0, 1e-6), _angle)
def test_euler123_near_gimbal_lock_rebuilds_the_matrix(roll, sign, offset, yaw):
    """Within 1e-6 rad of θ = ±90° only roll ± yaw is defined; the angles returned must
    still rebuild the same matrix, and θ itself must come back."""
    pitch = sign * (math.pi / 2 - offset)
    B = R.euler123_to_dcm(roll, pitch, yaw)
    r, p, y = R.dcm_to_euler123(B)
    np.testing.assert_allclose(R.euler123_to_dcm(r, p, y), B, atol=gimbal_lock_round_off)
    assert abs(p - pitch) < one_arcsecond * 1e-6


@FRAMES
@given(_quats, _quats, _quats)
def test_quat_multiply_agrees_with_matrix_products_and_associates(a, b, c):
    """Eq 4-10: C(quat_multiply(a, b)) = C(a) C(b); and (a b) c = a (b c)."""
    np.testing.assert_allclose(
        R.quat_to_dcm(R.quat_multiply(a, b)), R.quat_to_dcm(a) @ R.quat_to_dcm(b), atol=round_off
    )
    left = R.quat_multiply(R.quat_multiply(a, b), c)
    right = R.quat_multiply(a, R.quat_multiply(b, c))
    np.testing.assert_allclose(left, right, atol=round_off)
    np.testing.assert_allclose(R.quat_multiply(a, R.quat_conjugate(a)), [0, 0, 0, 1], atol=round_off)


@FRAMES
@given(_quats, st.floats(0.0, math.pi - 1e-6))
def test_rotvec_round_trip(axis_q, angle):
    """exp(−[φ×]) and back: φ returns for |φ| < π (at π, φ and −φ are the same rotation);
    tiny angles go through the series branch."""
    axis = axis_q[:3] / max(np.linalg.norm(axis_q[:3]), 1e-300)
    if np.linalg.norm(axis_q[:3]) < 1e-6:
        axis = np.array([0.0, 0.0, 1.0])
    phi = axis * angle
    Cm = R.rotvec_to_dcm(phi)
    np.testing.assert_allclose(Cm @ Cm.T, np.eye(3), atol=round_off)
    np.testing.assert_allclose(R.dcm_to_rotvec(Cm), phi, atol=round_off)
