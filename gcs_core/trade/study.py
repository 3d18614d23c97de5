"""Trade studies: the predictor over many data plans and sensor configurations (seed §1.1).

A :class:`StudyDefinition` is a base analysis config, the keys varied with their values
(:mod:`gcs_core.trade.space`), the *target* elements whose σ the analyst cares about and,
where the mission's ephemeris does not cover a plan, the orbit to tabulate one from. Each
combination is one plan; :func:`evaluate_plans` runs the predictor
(:func:`gcs_core.predictor.predict`, Eq 3-2 or Eq 3-4 with the configured method) on a
batch of them and returns one :class:`PlanRow` each: the final σ of every target element
(total and noise only), the attitude σ, the consider error budget of the targets and what
the plan leaves undetermined. Every plan is computed from its definition alone, so a plan
gives the same numbers serially, on any worker and in any order.

Ranking. Targets have different units, so plans are ranked by the geometric mean, over
the target elements, of ``σ / (the best σ of that element in the study)``: 1.0 is a plan
best at everything; an element a plan does not determine makes its score infinite.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from gcs_core.config_schema import AnalysisConfig
from gcs_core.errors import GcsError, InputError
from gcs_core.trade import space

log = logging.getLogger(__name__)

#: the pseudo-target of the three attitude angles (σ about the body axes at the plan end)
ATTITUDE = "attitude"
ATTITUDE_NAMES = ("attitude.roll", "attitude.pitch", "attitude.yaw")
#: the pseudo-target ``NAME.misalignment``: small rotations of sensor NAME about its own
#: axes x (a tracker's boresight), y, z, from the covariance of ``align_1..3``
MISALIGN = ("misalign_x", "misalign_y", "misalign_z")
#: a noise-only σ above this fraction of the a-priori σ is mostly the a priori's
PRIOR_LIMITED = 0.3
ORBIT_KEYS = ("a_km", "e", "i_deg", "raan_deg", "argp_deg", "mean_anomaly_deg")


@dataclass(frozen=True)
class StudyDefinition:
    """What a trade study computes (module docstring).

    Attributes
    ----------
    config_path : the base analysis config (TOML), read again by every worker.
    vary : key -> values (:mod:`gcs_core.trade.space`); the first key varies slowest.
    targets : element names (``TAM1.bias_x``), effect ids (``TAM1.alignment``: all its
        elements), a sensor's misalignment about its own axes (``FHST1.misalignment`` or
        ``FHST1.misalign_x``), or ``"attitude"`` (the default).
    orbit : Kepler elements (:data:`ORBIT_KEYS`); when given, every plan's ephemeris is
        tabulated from it (one ephemeris source for the whole study, any span or start),
        otherwise the mission's TLE or ephemeris file (:mod:`gcs_core.predictor.source`).
    method : ``"whole_span"``/``"batch"``/``"kalman"`` to override the config's, or None.
    top : how many best plans get their error budget printed.
    source : the plan read once on the submitting machine
        (:class:`~gcs_core.predictor.source.PlanSource`): what a worker computes from,
        shipped with the definition; None: read from ``config_path`` where it runs.
    """

    config_path: str
    vary: Mapping[str, tuple]
    targets: tuple[str, ...] = ()
    orbit: Mapping[str, float] | None = None
    method: str | None = None
    top: int = 3
    source: Any = field(default=None, compare=False, repr=False)

    def with_source(self) -> StudyDefinition:
        """This definition with its plan read (:func:`~gcs_core.predictor.source.load_source`)."""
        if self.source is not None:
            return self
        from gcs_core.predictor.source import load_source

        return replace(self, source=load_source(self.config_path, method=self.method))

    def combos(self) -> list[dict[str, Any]]:
        return space.combinations(self.vary)

    def as_json(self) -> str:
        return json.dumps(
            {
                "config_path": self.config_path,
                "vary": {k: list(v) for k, v in self.vary.items()},
                "targets": list(self.targets),
                "orbit": self.orbit,
                "method": self.method,
                "top": self.top,
            },
            sort_keys=True,
        )

    def digest(self) -> str:
        """Hash of everything the numbers depend on: the base config's settings and the
        mission description (not their paths), the varied keys and values, the targets,
        the orbit and the method."""
        d = json.loads(self.as_json())
        d.pop("config_path")
        d.pop("top")
        d["config"] = self.with_source().source.content
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]

    @classmethod
    def from_json(cls, text: str) -> StudyDefinition:
        d = json.loads(text)
        return cls(
            d["config_path"],
            {k: tuple(v) for k, v in d["vary"].items()},
            tuple(d["targets"]),
            d.get("orbit"),
            d.get("method"),
            int(d.get("top", 3)),
        )


@dataclass(frozen=True)
class PlanRow:
    """The predicted accuracy of one plan.

    Attributes
    ----------
    index : position of the combination in the study; plan_id : its stable name.
    values : the varied keys' values; description : the plan's full description.
    elements : the target element names (attitude as ``attitude.roll`` ...).
    sigma, noise_only : (n,) final total and noise-only 1-σ of each target element
        (internal units; attitude in rad); ∞ where the plan does not determine it, NaN
        where the element is not in the plan's state (its sensor is off).
    units : the elements' units.
    budget : consider element -> (n,) its σ contribution to each target.
    undetermined, unobservable : from the prediction.
    frames : sensor -> usable frames.
    prior_limited : (n,) True where the data alone cannot determine the element (it is in
        a combination the data cannot separate, or σ is its a priori): its σ is the a
        priori's doing, not the plan's.
    status : ``"ok"`` or the one-line reason the plan could not be predicted.
    seconds : time the prediction took (not part of the numbers compared across runs).
    warnings : the prediction's warnings (the batch method's computed warning).
    """

    index: int
    plan_id: str
    values: Mapping[str, Any]
    description: Mapping[str, Any]
    elements: tuple[str, ...]
    sigma: tuple[float, ...]
    noise_only: tuple[float, ...]
    units: tuple[str, ...]
    budget: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    undetermined: tuple[str, ...] = ()
    unobservable: tuple[str, ...] = ()
    frames: Mapping[str, int] = field(default_factory=dict)
    status: str = "ok"
    seconds: float = 0.0
    prior_limited: tuple[bool, ...] = ()
    warnings: tuple[str, ...] = ()

    def sigma_of(self, name: str) -> float:
        return self.sigma[self.elements.index(name)]

    def slew_min(self) -> float:
        return sum(m["duration"] for m in self.description.get("maneuvers", ())) / 60.0

    def data_h(self) -> float:
        d = self.description
        if "end" not in d:
            return math.nan
        gaps = sum(min(b, d["end"]) - max(a, d["start"]) for a, b in d.get("gaps", ()) if b > d["start"])
        return (d["end"] - d["start"] - gaps) / 3600.0


# ---------------------------------------------------------------------------- per process
_CONTEXT: dict[str, tuple] = {}
_TARGETS: dict[tuple, tuple] = {}


def _context(defn: StudyDefinition):
    """The study's :class:`~gcs_core.predictor.source.PlanSource`: the one shipped with the
    definition, else read once per process; its varied keys checked."""
    if defn.source is not None:
        return defn.source
    key = defn.as_json()
    src = _CONTEXT.get(key)
    if src is None:
        src = defn.with_source().source
        _CONTEXT.clear()  # one study at a time per process
        _CONTEXT[key] = src
    return src


def check_study(defn: StudyDefinition) -> None:
    """Refuse a varied key the plan space does not know (before any plan is computed)."""
    src = defn.with_source().source
    for k in defn.vary:
        space.check_key(k, src.spec)
        space.check_values(k, defn.vary[k])


def make_orbit(orbit: Mapping[str, float] | None, epoch):
    """A :class:`~gcs_core.ephem.orbit.KeplerOrbit` from the ``[trade.orbit]`` table, or None."""
    from gcs_core.predictor.source import kepler_orbit

    return kepler_orbit(orbit, epoch)


def target_elements(targets: Sequence[str], spec) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Expand targets to (element names, units): effect ids to their elements (from the
    sensors' models), ``attitude`` to the three attitude angles."""
    from gcs_core.models import make_model

    params: dict[str, list[tuple[str, str]]] = {}
    for s in spec.sensors:
        try:
            for p in make_model(s).parameters():
                params.setdefault(f"{s.name}.{p.effect}", []).append((p.element or f"{s.name}.{p.name}", p.unit))
                params[p.element or f"{s.name}.{p.name}"] = [(p.element or f"{s.name}.{p.name}", p.unit)]
        except GcsError:
            continue
    gyro = [s.name for s in spec.sensors if s.type == "gyro"]
    names, units = [], []
    for t in targets:
        if t == ATTITUDE:
            found = [(n, "rad") for n in ATTITUDE_NAMES]
        elif t in ATTITUDE_NAMES:
            found = [(t, "rad")]
        elif t.rpartition(".")[2] in MISALIGN and f"{t.rpartition('.')[0]}.alignment" in params:
            found = [(t, "rad")]
        elif t.endswith(".misalignment") and f"{t[: -len('.misalignment')]}.alignment" in params:
            found = [(f"{t[: -len('.misalignment')]}.{m}", "rad") for m in MISALIGN]
        elif t in params:
            found = params[t]
        elif gyro and t.startswith(f"{gyro[0]}.bias_rate"):
            found = [(t, "rad/s2")]
        else:
            raise InputError(
                f"unknown target '{t}': give an element (TAM1.bias_x), an effect id "
                "(TAM1.alignment, see gcs effects), a sensor's misalignment about its "
                "own axes (FHST1.misalignment, FHST1.misalign_x) or 'attitude'",
                key="trade.targets",
            )
        for n, u in found:
            if n not in names:
                names.append(n)
                units.append(u)
    return tuple(names), tuple(units)


def evaluate_plans(defn: StudyDefinition, items: Sequence[tuple[int, Mapping[str, Any]]]) -> list[PlanRow]:
    """Predict each ``(index, combination)`` of ``items`` (a batch of one task)."""
    src = _context(defn)
    cfg, spec, base = src.config, src.spec, src.plan
    targets = defn.targets or (ATTITUDE,)  # without targets: the attitude
    key = (targets, src.content, id(spec))  # once per process, not once per batch
    if key not in _TARGETS:
        _TARGETS.clear()
        _TARGETS[key] = target_elements(targets, spec)
    names, units = _TARGETS[key]
    out = []
    for index, combo in items:
        t0 = time.perf_counter()
        pid = space.plan_id(combo)
        try:
            setup = space.apply(cfg, spec, base, combo)
            res = src.predict(setup.plan, config=setup.config, spec=setup.spec)
        except (GcsError, np.linalg.LinAlgError) as err:
            log.info("plan %s: %s", pid, err)
            desc = {}
            try:
                desc = space.apply(cfg, spec, base, combo).describe()
            except GcsError:
                pass
            nan = (math.nan,) * len(names)
            out.append(
                PlanRow(
                    index,
                    pid,
                    dict(combo),
                    desc,
                    names,
                    nan,
                    nan,
                    units,
                    status=" ".join(str(err).split()),
                    seconds=time.perf_counter() - t0,
                )
            )
            continue
        out.append(_row(index, pid, combo, setup, res, names, units, time.perf_counter() - t0))
    return out


def sensor_axes_covariance(spec, sensor: str, P_align: np.ndarray) -> np.ndarray:
    """(3, 3) covariance of the small rotation ``φ_S`` about the sensor's own axes, from the
    covariance of its alignment angles (ICD §2: ``M = T3(a3) T2(a2) T1(a1)``, ``v_S = M v_B``).

    ``M(a + δa) ≈ (I − [φ_S×]) M(a)`` gives ``[φ_S×] = −Σ_k ∂M/∂a_k Mᵀ δa_k``, so
    ``φ_S = J δa`` with column k of J the axial vector of ``−∂M/∂a_k Mᵀ``; ``P_φ = J P_a Jᵀ``.
    (``a1`` turns about the *body* x axis, the sensor's x only when ``a2 = a3 = 0``.)
    """
    from gcs_core.frames.rotations import euler123_partials, euler123_to_dcm
    from gcs_core.units import DEG

    a = np.asarray(spec.sensor(sensor).alignment_deg or (0.0, 0.0, 0.0), float) * DEG
    M, dM = euler123_to_dcm(*a), euler123_partials(*a)
    J = np.zeros((3, 3))
    for k in range(3):
        W = -dM[k] @ M.T
        J[:, k] = (W[2, 1], W[0, 2], W[1, 0])
    return J @ P_align @ J.T


def _misalignment(res, spec, name: str, total: bool) -> float:
    sensor, _, axis = name.rpartition(".")
    al = [f"{sensor}.align_{k}" for k in (1, 2, 3)]
    if not all(a in res.names for a in al):
        return math.nan
    idx = [res.index(a) for a in al]
    P = (res.P_consider if total else res.P)[np.ix_(idx, idx)]
    if not np.all(np.isfinite(res.noise_only[idx])):
        return math.inf
    Pphi = sensor_axes_covariance(spec, sensor, P)
    return float(np.sqrt(max(Pphi[MISALIGN.index(axis), MISALIGN.index(axis)], 0.0)))


def _row(index, pid, combo, setup, res, names, units, seconds) -> PlanRow:
    sig, noise = [], []
    cols: list = []
    for n in names:
        if n.rpartition(".")[2] in MISALIGN:
            sig.append(_misalignment(res, setup.spec, n, True))
            noise.append(_misalignment(res, setup.spec, n, False))
            cols.append(None)
        elif n in ATTITUDE_NAMES:
            a = float(res.attitude_sigma[-1, ATTITUDE_NAMES.index(n)])
            sig.append(a)
            noise.append(a)
            cols.append(None)
        elif n in res.names:
            i = res.index(n)
            sig.append(float(res.sigma[-1, i]))
            noise.append(float(res.noise_only[i]))
            cols.append(i)
        else:
            sig.append(math.nan)
            noise.append(math.nan)
            cols.append(None)
    budget = {c: tuple(float(v[i]) if i is not None else 0.0 for i in cols) for c, v in res.budget.items()}
    return PlanRow(
        index,
        pid,
        dict(combo),
        setup.describe(),
        names,
        tuple(sig),
        tuple(noise),
        units,
        budget,
        tuple(res.undetermined),
        tuple(res.unobservable),
        dict(res.frames),
        "ok",
        seconds,
        tuple(_prior_limited(n, res, setup.spec, x) for n, x in zip(names, noise)),
        tuple(res.warnings),
    )


def _prior_limited(name: str, res, spec, noise: float) -> bool:
    """The σ is mostly the a priori's (:attr:`PlanRow.prior_limited`): the noise-only σ is
    above :data:`PRIOR_LIMITED` of the a-priori σ (the data give less than about ten
    times the prior information about the element)."""
    if res.prior is None or not math.isfinite(noise):
        return False
    if name in ATTITUDE_NAMES:
        prior = (
            float(np.max(res.prior[[res.index(n) for n in ("att.roll", "att.pitch", "att.yaw")]]))
            if all(n in res.names for n in ("att.roll", "att.pitch", "att.yaw"))
            else math.inf
        )
    elif name.rpartition(".")[2] in MISALIGN:
        sensor, _, axis = name.rpartition(".")
        al = [f"{sensor}.align_{k}" for k in (1, 2, 3)]
        if not all(a in res.names for a in al):
            return False
        P0 = np.diag(np.square(res.prior[[res.index(a) for a in al]]))
        prior = float(np.sqrt(sensor_axes_covariance(spec, sensor, P0)[MISALIGN.index(axis), MISALIGN.index(axis)]))
    elif name in res.names:
        prior = float(res.prior[res.index(name)])
    else:
        return False
    return bool(math.isfinite(prior) and noise > PRIOR_LIMITED * prior)


# ---------------------------------------------------------------------------- ranking
def scores(rows: Sequence[PlanRow]) -> np.ndarray:
    """(k,) ranking score of each row (module docstring); ∞ for a plan that fails a target,
    NaN for a plan that could not be predicted."""
    if not rows:
        return np.zeros(0)
    S = np.array([r.sigma for r in rows], dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = np.isfinite(S) & (S > 0)
        best = np.array([np.min(S[ok[:, j], j]) if np.any(ok[:, j]) else np.nan for j in range(S.shape[1])])
        rel = S / best[None, :]
        rel = np.where(np.isnan(S), np.inf, rel)
        out = np.exp(np.mean(np.log(rel), axis=1))
    failed = np.array([r.status != "ok" for r in rows])
    out[failed] = np.nan
    return out


def ranked(rows: Sequence[PlanRow]) -> list[tuple[float, PlanRow]]:
    """Rows sorted best first (failed plans last)."""
    sc = scores(rows)
    order = sorted(
        range(len(rows)), key=lambda i: (np.isnan(sc[i]), sc[i] if np.isfinite(sc[i]) else np.inf, rows[i].index)
    )
    return [(float(sc[i]), rows[i]) for i in order]


def definition_from_config(
    cfg: AnalysisConfig,
    vary: Mapping[str, tuple] | None = None,
    targets: Sequence[str] | None = None,
    *,
    method: str | None = None,
    top: int | None = None,
) -> StudyDefinition:
    """The study of a config's ``[trade]`` table. Command-line ``vary`` merges into the
    table's ``[trade.vary]`` (a key given on the command line replaces that key's values;
    the table's other keys, ``maneuver.back = true`` or ``start_min`` say, stay); command-
    line ``targets`` replace the table's."""
    if cfg.path is None:
        raise InputError("a trade study needs its analysis config on disk", key="trade")
    tr = dict(getattr(cfg, "trade", {}) or {})
    table = tr.get("vary", {})
    if not isinstance(table, dict):
        raise InputError("must be a table of KEY = [values]", key="trade.vary")
    v = space.merge_vary(
        {k: tuple(val) if isinstance(val, (list, tuple)) else (val,) for k, val in table.items()}, dict(vary or {})
    )
    if not v:
        raise InputError("nothing to vary: give --vary KEY=VALUES or a [trade.vary] table", key="trade.vary")
    tg = tuple(targets) if targets else tuple(tr.get("targets", ()))
    return StudyDefinition(
        str(Path(cfg.path).resolve()), v, tg, tr.get("orbit"), method, int(top if top is not None else tr.get("top", 3))
    )


__all__ = [
    "ATTITUDE",
    "PlanRow",
    "StudyDefinition",
    "definition_from_config",
    "evaluate_plans",
    "make_orbit",
    "ranked",
    "scores",
    "sensor_axes_covariance",
    "target_elements",
]
