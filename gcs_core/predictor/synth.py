"""Standard Data File headers from data modeling (seed §3.2.2, §4.3): a Problem without data.

"In the case of a predictor ... only the header information of SDF, which gives the
time and the amount of data, needs to be generated. There is no need of simulating the
actual data content." :func:`plan_problem` builds, for a :class:`DataPlan`, the same
:class:`~gcs_core.problem.build.Problem` the calibration would build from telemetry —
same SODL state, same models, same reference vectors — from frame *times* only:

1. frame times per sensor: the cadence slots of the span, minus the gaps, minus the
   slots where the sensor cannot see (:func:`gcs_core.predictor.nominal.available`)
   and, for a star tracker with a catalog, those with no catalog star in the field;
   or, with ``plan.frames = "telemetry"``, the telemetry's own times;
2. telemetry tables holding those times and placeholder values, except what the
   geometry needs: the identified star of a tracker frame
   (:mod:`gcs_core.predictor.stars`: with ``plan.stars`` = ``"catalog"``,
   ``"telemetry"`` or ``"sky"`` a star of that catalog in the field, drawn ∝
   brightness by :func:`~gcs_core.predictor.stars.catalog_stars`; with ``"uniform"``
   one spread evenly over the field, :func:`~gcs_core.predictor.stars.synthetic_stars`),
   a spinner's spin rate, and the gyro rates that carry the nominal attitude (Eq 4-32
   with Eq 4-33 rates);
3. :func:`~gcs_core.problem.build.build_problem` on those tables, the attitude
   elements set to the nominal attitude at ``start``, and each sensor's ``y`` replaced
   by its prediction at the nominal state, so every residual is zero and only the
   partials ``H`` carry information.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gcs_core.ephem.ephemeris import EPHEMERIS_COLUMNS, Ephemeris
from gcs_core.errors import InputError
from gcs_core.frames.reference import ra_dec_from_vector
from gcs_core.frames.rotations import dcm_to_euler123, quat_normalize, quat_to_dcm
from gcs_core.io.importer import TELEMETRY_COLUMNS, ImportedMission
from gcs_core.io.types import MissionSpec, SensorSpec, Table
from gcs_core.models import make_model
from gcs_core.models.base import Geometry
from gcs_core.predictor.nominal import PlanAttitude, available, nominal_spin_axis
from gcs_core.predictor.plan import DEFAULT_CADENCE_S, DEFAULT_TRACKER_CADENCE_S, DataPlan
from gcs_core.predictor.stars import (
    STAR_CATALOG_FILE,
    catalog_stars,
    default_sky,
    read_catalog,
    synthetic_stars,
    telemetry_catalog,
)
from gcs_core.problem.attitude import RPY, ManeuverAttitude, ReferenceAttitude
from gcs_core.problem.build import Problem, StateOptions, build_problem
from gcs_core.problem.gyro_attitude import GyroAttitude
from gcs_core.problem.linearization import linearize
from gcs_core.problem.prepare import PhysicsOptions
from gcs_core.units import DEG

SPINNER_TYPES = ("plane_field_sun", "horizon")
#: room left at the end of a spinner plan for the horizon model's time shifts [s]
SPINNER_MARGIN_S = 2.0


@dataclass
class PlannedProblem:
    """A Problem built from a data plan, with its bookkeeping.

    Attributes
    ----------
    problem : the Problem (observation sensors with zero residuals).
    values : element values at which it is linearized (the nominal state).
    nominal : the nominal attitude (None for a Problem given directly).
    cadence : sensor -> frame spacing [s].
    slots : sensor -> cadence slots in the plan span (the denominator of availability).
    """

    problem: Problem
    values: dict
    nominal: PlanAttitude | None
    cadence: dict
    slots: dict


def ephemeris_table(eph: Ephemeris) -> Table:
    """An ephemeris.csv :class:`Table` (ICD §4 columns) holding ``eph``'s rows."""
    cols = dict(zip(EPHEMERIS_COLUMNS, [eph.t, *eph.r_I_km.T, *eph.v_I_km_s.T, *eph.sun_I_km.T]))
    cols = {k: np.array(v, dtype=float) for k, v in cols.items()}
    return Table(path=Path(eph.source), t=cols["t"], columns=cols, lines=np.arange(2, eph.t.size + 2))


def median_step(t) -> float | None:
    t = np.asarray(t, dtype=float)
    return float(np.median(np.diff(t))) if t.size >= 2 else None


def spin_rate_of(spec: MissionSpec, telemetry: Mapping[str, Table], plan: DataPlan) -> float:
    """Spin rate [rad/s]: the plan's, the horizon telemetry's median, or ``spin_rate_rpm``."""
    if plan.spin_rate is not None:
        return float(plan.spin_rate)
    for s in spec.sensors:
        tab = telemetry.get(s.name)
        if s.type == "horizon" and tab is not None and len(tab):
            return float(np.median(np.abs(tab.columns["spin_rate"])))
    for s in spec.sensors:
        rpm = s.get("spin_rate_rpm")
        if rpm is not None:
            return float(rpm) * 2.0 * np.pi / 60.0
    raise InputError(
        "a spinning mission's plan needs the spin rate: give DataPlan.spin_rate, "
        "horizon telemetry, or the data-book key spin_rate_rpm",
        key="prediction.spin_rate",
    )


def cadence_of(sensor: SensorSpec, table: Table | None, plan: DataPlan, spin_rate: float | None = None) -> float:
    """Frame spacing [s] (plan > telemetry > ``cadence`` book key > default; spinners: a spin)."""
    if sensor.name in plan.cadence:
        return float(plan.cadence[sensor.name])
    if sensor.type in SPINNER_TYPES and spin_rate:
        return 2.0 * np.pi / spin_rate
    if table is not None:
        step = median_step(table.t)
        if step:
            return step
    book = sensor.get("cadence")
    if book is not None:
        value = float(book)
        if not value > 0:
            raise InputError("cadence must be > 0", key=f"{sensor.name}.cadence")
        return value
    return DEFAULT_TRACKER_CADENCE_S if sensor.type == "star_tracker" else DEFAULT_CADENCE_S


def _table(name: str, t: np.ndarray, columns: Mapping[str, np.ndarray]) -> Table:
    cols = {"t": np.asarray(t, dtype=float)}
    cols.update({k: np.asarray(v, dtype=float) for k, v in columns.items()})
    return Table(path=Path(f"<plan {name}>"), t=cols["t"], columns=cols, lines=np.arange(1, t.size + 1))


def _subset(table: Table, mask: np.ndarray) -> Table:
    return replace(
        table,
        t=table.t[mask],
        columns={k: np.asarray(v)[mask] for k, v in table.columns.items()},
        lines=np.asarray(table.lines)[mask],
    )


def _synthetic_table(
    sensor: SensorSpec, t: np.ndarray, nominal: PlanAttitude, spin_rate: float | None, stars_I: np.ndarray | None = None
) -> Table:
    """Placeholder telemetry at ``t`` (module docstring, step 2); ``stars_I`` (N, 3) the
    identified stars of a tracker (default: spread evenly over its field)."""
    n = t.size
    zero = np.zeros(n)
    if sensor.type == "star_tracker":
        if stars_I is None:
            stars_I = synthetic_stars(sensor, t, nominal)
        ra, dec = ra_dec_from_vector(stars_I)
        return _table(sensor.name, t, {"h": zero, "v": zero, "ra": ra / DEG, "dec": dec / DEG, "mag": np.full(n, 4.0)})
    if sensor.type == "horizon":
        return _table(sensor.name, t, {"spin_rate": np.full(n, spin_rate), "dt_in": zero, "dt_out": zero})
    return _table(sensor.name, t, {c: zero for c in TELEMETRY_COLUMNS[sensor.type][1:]})


def _gyro_table(sensor: SensorSpec, plan: DataPlan, cadence: float, nominal: PlanAttitude) -> Table:
    """Gyro rows at ``start + k·cadence`` (k ≥ 1) reading the nominal rates (Eq 4-32, 4-33)."""
    rows = plan.grid(cadence, first=plan.start + cadence)
    if rows.size == 0:
        raise InputError(f"the plan span is shorter than one gyro interval ({cadence} s)", key="prediction.end")
    omega = nominal.mean_rates(np.concatenate([[plan.start], rows]))
    model = make_model(sensor)
    y = model.predict(Geometry(t=rows, omega_B=omega), {}).y
    return _table(sensor.name, rows, {"wx": y[:, 0], "wy": y[:, 1], "wz": y[:, 2]})


def star_catalog(spec: MissionSpec, plan: DataPlan, telemetry: Mapping[str, Table]):
    """The catalog of ``plan.stars`` (None for ``"uniform"``).

    ``"catalog"``: ``plan.catalog`` (relative to the mission directory), else the
    mission's ``star_catalog.csv``; ``"telemetry"``: the distinct stars of the trackers'
    telemetry; ``"sky"``: the synthetic sky.
    """
    if plan.stars == "uniform":
        return None
    if plan.stars == "sky":
        return default_sky()
    if plan.stars == "telemetry":
        cat = telemetry_catalog(
            telemetry[s.name] for s in spec.sensors if s.type == "star_tracker" and s.name in telemetry
        )
        if cat is None:
            raise InputError(
                'stars = "telemetry" needs star-tracker telemetry with identified stars '
                "(none in this mission): give a catalog instead",
                key="prediction.stars",
            )
        return cat
    path = plan.catalog
    root = Path(spec.root) if spec.root is not None else None
    if path is None:
        if root is None or not (root / STAR_CATALOG_FILE).is_file():
            raise InputError(
                f'stars = "catalog" needs a star catalog: give prediction.catalog (CSV ra, '
                f"dec, mag) or put {STAR_CATALOG_FILE} in the mission directory",
                key="prediction.catalog",
            )
        path = root / STAR_CATALOG_FILE
    elif not path.is_absolute() and root is not None:
        path = root / path
    if not path.is_file():
        raise InputError("star catalog file not found", file=path, key="prediction.catalog")
    return read_catalog(path)


def _rpy0(spec: MissionSpec, plan: DataPlan, eph: Ephemeris, onboard: Table | None) -> np.ndarray:
    """Nominal roll/pitch/yaw at ``start``: the plan's, the onboard attitude's, or zeros."""
    if plan.rpy0 is not None:
        return np.asarray(plan.rpy0, dtype=float)
    if onboard is not None and len(onboard) and onboard.t[0] <= plan.start <= onboard.t[-1]:
        k = int(np.argmin(np.abs(onboard.t - plan.start)))
        q = quat_normalize(np.array([onboard.columns[c][k] for c in ("q1", "q2", "q3", "q4")]))
        A = ReferenceAttitude(spec.attitude_mode, eph).reference(np.array([plan.start]))[0]
        return np.array(dcm_to_euler123(quat_to_dcm(q) @ A.T), dtype=float)
    return np.zeros(3)


def plan_problem(
    spec: MissionSpec,
    eph: Ephemeris,
    plan: DataPlan,
    *,
    telemetry: Mapping[str, Table] | None = None,
    aux: Table | None = None,
    onboard: Table | None = None,
    physics: PhysicsOptions | None = None,
    options: StateOptions | None = None,
    use_gyro: bool = True,
    catalog=None,
) -> PlannedProblem:
    """Headers-only Problem of ``spec`` for ``plan`` (module docstring).

    Parameters
    ----------
    spec : the mission description (sensors and data-book values).
    eph : an ephemeris covering ``[plan.start, plan.end]``.
    plan : the data plan.
    telemetry : sensor -> telemetry Table, where there is one (cadences; and the frames
        themselves with ``plan.frames = "telemetry"``).
    aux, onboard : auxiliary channels (magnetometer contamination) and onboard attitude
        (nominal attitude at ``start``), optional.
    physics, options : as for :func:`~gcs_core.problem.build.build_problem`.
    use_gyro : carry the attitude by the gyro if the mission has one.
    catalog : the star catalog already read (a plan read on another machine,
        :mod:`gcs_core.predictor.source`); None: :func:`star_catalog`.
    """
    telemetry = dict(telemetry or {})
    eph.check_covers(np.array([plan.start, plan.end]), what="the prediction plan")
    from_tm = plan.frames == "telemetry"
    spinning = spec.attitude_mode == "spinning"
    spin_rate = spin_rate_of(spec, telemetry, plan) if spinning else None
    if spinning:
        if spec.spin_axis_guess_deg is None:
            raise InputError(
                "a spinning mission needs spin_axis_guess_deg = [RA, Dec] (the nominal axis)",
                file=spec.root / "mission.toml",
                key="mission.spin_axis_guess_deg",
            )
        nominal = PlanAttitude("spinning", eph, plan, spin_axis_I=nominal_spin_axis(*spec.spin_axis_guess_deg))
    else:
        nominal = PlanAttitude(spec.attitude_mode, eph, plan, _rpy0(spec, plan, eph, onboard))
    gyros = [s for s in spec.sensors if s.type == "gyro"]
    gyro = gyros[0] if (gyros and use_gyro and not spinning) else None
    trackers = any(s.type == "star_tracker" for s in spec.sensors)
    if catalog is None or plan.stars != "catalog":
        catalog = star_catalog(spec, plan, telemetry) if (trackers and not from_tm) else None

    tables: dict[str, Table] = {}
    cadence: dict[str, float] = {}
    slots: dict[str, int] = {}
    empty: list[str] = []
    for s in spec.sensors:
        tab = telemetry.get(s.name)
        c = cadence_of(s, tab, plan, spin_rate)
        cadence[s.name] = c
        slots[s.name] = int(plan.grid(c).size)
        if s.type == "gyro":
            if from_tm and tab is not None:
                tables[s.name] = _subset(tab, (tab.t > plan.start - 10 * c) & (tab.t <= plan.end + c))
            else:
                tables[s.name] = _gyro_table(s, plan, c, nominal)
            continue
        if from_tm and tab is not None:
            keep = plan.in_span(tab.t) & ~plan.in_gap(tab.t, s.name)
            table = _subset(tab, keep)
        else:
            if s.type in SPINNER_TYPES:
                # sightings from half a spin in; the horizon crossing (up to a spin later,
                # and the model's ±1 s differences) must stay inside the ephemeris
                t = plan.grid(c, first=plan.start + 0.5 * c)
                t = t[t <= plan.end - c - SPINNER_MARGIN_S]
            else:
                t = plan.grid(c)
            t = t[~plan.in_gap(t, s.name)]
            t = t[available(s, t, nominal)] if t.size else t
            stars_I = None
            if s.type == "star_tracker" and catalog is not None:
                seen, stars_I = catalog_stars(s, t, nominal, catalog)
                t, stars_I = t[seen], stars_I[seen]
            table = _synthetic_table(s, t, nominal, spin_rate, stars_I)
        if len(table) == 0:
            # keep the sensor's elements in the state: one placeholder frame mid-span,
            # dropped below
            empty.append(s.name)
            table = _synthetic_table(s, np.array([0.5 * (plan.start + plan.end)]), nominal, spin_rate)
        tables[s.name] = table

    mission = ImportedMission(
        spec=spec, ephemeris_table=ephemeris_table(eph), telemetry=tables, aux=aux, onboard=onboard if from_tm else None
    )
    problem = build_problem(mission, physics=physics, options=options, use_gyro=gyro is not None)
    if not from_tm:
        if spinning:
            nominal_values = {}
        else:
            rpy_start = nominal.rpy(np.array([plan.start]))[0]
            nominal_values = dict(zip(RPY, map(float, rpy_start)))
            if not isinstance(problem.attitude, GyroAttitude):
                problem.attitude = ManeuverAttitude(ReferenceAttitude(spec.attitude_mode, eph), plan.maneuver_offsets)
        problem = problem.with_state(problem.state.with_values(nominal_values))
    problem.sensors = [sd for sd in problem.sensors if sd.name not in empty]
    values = problem.state.values()
    zero_residuals(problem, values)
    return PlannedProblem(problem, values, None if from_tm else nominal, cadence, slots)


def zero_residuals(problem: Problem, values: Mapping[str, float]) -> None:
    """Replace each sensor's ``y`` by its prediction at ``values`` (valid frames)."""
    lins = {lin.name: lin for lin in linearize(problem, values, [])}
    out = []
    for sd in problem.sensors:
        lin = lins[sd.name]
        y = np.where(lin.valid[:, None], lin.y_pred, sd.y)
        out.append(replace(sd, y=y))
    problem.sensors = out
