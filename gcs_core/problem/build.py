"""A calibration problem: state definition + sensors + attitude provider (SODL + SIDP).

:func:`build_problem` is where choosing the observation and transition models defines
the state vector automatically (seed §3.2.2, Table 3-1): every parameter of every
chosen model becomes a named element, the attitude provider adds its own, and roles
and a-priori values come from the analysis configuration.

:mod:`gcs_core.problem.linearization` (:func:`~gcs_core.problem.linearization.iter_blocks`,
:func:`~gcs_core.problem.linearization.linearize`) is the single place where predictions
and partials of all sensors are assembled into residuals ``r = y − h(x)`` and Jacobian
columns ``H = ∂h/∂x``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np

from gcs_core.ephem.ephemeris import Ephemeris
from gcs_core.errors import ConfigError, InputError
from gcs_core.frames.rotations import euler123_to_dcm, quat_normalize, quat_to_dcm
from gcs_core.models import make_model
from gcs_core.models.base import ParamSpec
from gcs_core.models.gyro_noise import gyro_noise
from gcs_core.models.gyro_steps import GyroStepModel, gyro_step_channels
from gcs_core.problem.attitude import RADEC, RPY, AttitudeProvider, ReferenceAttitude, SpinAttitude, rpy_specs
from gcs_core.problem.gyro_attitude import GyroAttitude
from gcs_core.problem.prepare import GeometryBuilder, HeldChannels, PhysicsOptions, SensorData, prepare_sensors
from gcs_core.problem.state import HELD, SOLVE_FOR, Element, StateVector
from gcs_core.units import DEG

#: frames per chunk of the streaming linearization: memory is bounded by the chunk, not
#: the span. Large enough that per-chunk overheads are small, small enough that a chunk's
#: H and the gyro block it reads stay in the processor's cache between being written and
#: being summed (measured best near 16k frames on the batch benchmark)
CHUNK_FRAMES = 16_384


@dataclass(frozen=True)
class ElementOverride:
    """Per-element settings from the analysis config (all optional)."""

    role: str | None = None
    value: float | None = None
    sigma: float | None = None


@dataclass(frozen=True)
class StateOptions:
    """How SODL sets roles: which effects are in the state, and per-element overrides.

    Attributes
    ----------
    effects : extra catalogue effects to solve for, as ``<SENSOR>.<effect>`` ids.
    exclude : seed effects to hold instead, same ids.
    overrides : element name -> :class:`ElementOverride`.
    attitude_sigma : a-priori 1-sigma of the attitude elements [rad].
    """

    effects: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    overrides: Mapping[str, ElementOverride] = field(default_factory=dict)
    attitude_sigma: float = 1.0 * DEG


@dataclass
class Problem:
    """Everything the estimators need.

    Attributes
    ----------
    state : every element (all roles).
    attitude : the attitude provider (Reference/Gyro/Spin, :class:`AttitudeProvider`).
    sensors : observation sensors (gyros excluded; they drive the attitude).
    param_map : sensor -> {local param name -> element name}.
    builder : reference-vector builder (for variants and new times).
    tables : telemetry tables by sensor (for geometry variants).
    gyro_name : name of the gyro carrying the attitude, if any.
    chunk_frames : frames per chunk of the streaming linearization (:func:`iter_blocks`).
    """

    state: StateVector
    attitude: AttitudeProvider
    sensors: list[SensorData]
    param_map: dict[str, dict[str, str]]
    builder: GeometryBuilder
    tables: dict
    mode: str
    gyro_name: str | None = None
    edited: dict[str, np.ndarray] = field(default_factory=dict)
    chunk_frames: int = CHUNK_FRAMES

    @property
    def gyro_attitude(self) -> GyroAttitude:
        """The attitude provider as carried by the gyro (``gyro_name`` set): a
        :class:`GyroAttitude`, or a wrapper (the smoother's corrected attitude) that forwards
        its attributes; for the type checker only, nothing is converted or checked here."""
        return cast(GyroAttitude, self.attitude)

    def set_chunk(self, frames: int) -> None:
        """Chunk length of the streaming linearization and of the gyro propagation blocks
        (results do not depend on it beyond round-off; memory and speed do)."""
        self.chunk_frames = max(1, int(frames))
        if isinstance(self.attitude, GyroAttitude):
            self.attitude.block_knots = self.chunk_frames

    def sensor(self, name: str) -> SensorData:
        for s in self.sensors:
            if s.name == name:
                return s
        raise KeyError(name)

    def params_of(self, sensor: str, values: Mapping[str, float]) -> dict[str, float]:
        return {local: values[el] for local, el in self.param_map[sensor].items()}

    def with_state(self, state: StateVector) -> Problem:
        return replace(self, state=state)


def _effect_id(sensor: str | None, effect: str) -> str:
    return f"{sensor or 'model'}.{effect}"


def _element_from_spec(sensor: str | None, spec: ParamSpec, role: str, kind: str = "sensor") -> Element:
    name = spec.element or f"{sensor}.{spec.name}"
    return Element(
        name=name,
        unit=spec.unit,
        role=role,
        value=spec.nominal,
        sigma0=spec.sigma,
        sensor=sensor,
        param=spec.name,
        effect=spec.effect,
        seed=spec.seed,
        kind=kind,
        description=spec.description,
    )


def default_role(sensor_type: str, spec: ParamSpec, sensor=None) -> str:
    """SODL default: seed parameters are solved for, extended physics held.

    Sensor alignments are held by default even where the seed lists them (Eq 4-31):
    the body frame needs a reference, and the seed notes (§2.1.2, §2.2.2) that
    alignment and attitude separate only with enough geometry; the analyst adds them.
    A gyro whose data book declares a rate random walk (``rrw`` > 0) has a wandering
    bias: its bias instability (a linear drift over the span) is solved for too.
    """
    if spec.effect == "bias_instability" and sensor is not None and gyro_noise(sensor).sigma_u > 0:
        return SOLVE_FOR
    if not spec.seed or spec.effect == "alignment":
        return HELD
    return SOLVE_FOR


def unseen_at_prior(model) -> set[str]:
    """Parameters of ``model`` the data cannot see at the a priori: those it declares seen
    only through amplitudes (``ObservationModel.seen_through``) whose data-book values are
    all 0 — the fine Sun sensor's frequency ``k`` of ``A3 sin(k tan α)`` (Eq 4-23) when the
    book gives ``A3 = 0``.

    Such a frequency is held at its book value by default. Its information is ∝ A3², zero
    at the a priori, so Gauss–Newton steps in it are set by whatever the model misses: a
    second harmonic ``H sin(2k tan α)`` is exactly ``A3' sin(k' tan α)`` with ``k' = 2k``,
    and a free ``k`` slides along that alias (the fit's cost has many minima in ``k``, and
    ``(k, A3, A4h)`` and ``(−k, −A3, −A4h)`` give the same data). Holding it costs nothing
    when the amplitude is truly 0 (the data do not depend on ``k`` there) and keeps the
    harmonic a distinct effect for discovery; an analyst who expects a ripple gives its
    amplitude in the data book (``k`` is then solved for) or overrides the role.
    """
    seen = getattr(model, "seen_through", None) or {}
    if not seen:
        return set()
    nominal = {p.name: p.nominal for p in model.parameters()}
    return {name for name, amps in seen.items() if all(nominal.get(a, 0.0) == 0.0 for a in amps)}


def initial_attitude(mission, attitude, mode: str) -> dict[str, float]:
    """A-priori attitude element values.

    Spinning: the mission's ``spin_axis_guess_deg``. Three-axis: roll/pitch/yaw of the
    first onboard quaternion at ``t_ref`` relative to the reference frame, else of the
    first attitude reference sensor's quaternion there, else zeros.
    """
    spec = mission.spec
    if mode == "spinning":
        guess = spec.spin_axis_guess_deg
        if guess is None:
            raise InputError(
                "a spinning mission needs spin_axis_guess_deg = [RA, Dec]",
                file=spec.root / "mission.toml",
                key="mission.spin_axis_guess_deg",
            )
        return {"att.ra": guess[0] * DEG, "att.dec": guess[1] * DEG}
    ob = mission.onboard
    alignment = np.eye(3)
    if ob is None or not len(ob):
        # no onboard attitude: the first attitude reference sensor (its instrument frame
        # taken through its data-book alignment, C = Mᵀ C_SI)
        refs = [
            s
            for s in spec.sensors
            if s.type == "attitude_reference" and s.name in mission.telemetry and len(mission.telemetry[s.name])
        ]
        if refs:
            ob = mission.telemetry[refs[0].name]
            a = [v * DEG for v in (refs[0].alignment_deg or (0.0, 0.0, 0.0))]
            alignment = euler123_to_dcm(*a)
    if ob is not None and len(ob):
        t_ref = attitude.t_ref if attitude.t_ref is not None else float(ob.t[0])
        k = int(np.argmin(np.abs(ob.t - t_ref)))
        q = quat_normalize(np.array([ob.columns[c][k] for c in ("q1", "q2", "q3", "q4")]))
        roll, pitch, yaw = attitude.ref.rpy_from_dcm(alignment.T @ quat_to_dcm(q), t_ref)
        return {"att.roll": roll, "att.pitch": pitch, "att.yaw": yaw}
    return {n: 0.0 for n in RPY}


def build_problem(
    mission,
    *,
    physics: PhysicsOptions | None = None,
    options: StateOptions | None = None,
    use_gyro: bool = True,
    chunk_frames: int = CHUNK_FRAMES,
    families: Mapping[str, Sequence[str]] | None = None,
) -> Problem:
    """SODL + SIDP: the state vector and prepared sensors of an imported mission.

    The problem keeps what estimation needs (prepared sensors, the gyro rates, the
    telemetry columns geometry variants read again), not the mission: a caller that
    has no further use for the mission may drop it. ``families``: sensor -> generic family
    effects (``alignment_vs_tam_temp``, :mod:`gcs_core.models.drift`) its model gains.
    """
    spec = mission.spec
    physics = physics or PhysicsOptions()
    options = options or StateOptions()
    eph = Ephemeris.from_table(mission.ephemeris_table, margin_s=getattr(mission, "ephemeris_margin_s", 0.0))
    builder = GeometryBuilder(spec, eph, physics, mission.aux)
    sensors = prepare_sensors(spec, mission.telemetry, builder)
    if families:
        sensors = _with_families(sensors, families, builder)
    mode = spec.attitude_mode
    gyros = [s for s in spec.sensors if s.type == "gyro"]
    attitude = _attitude_provider(mission, eph, gyros, use_gyro, chunk_frames, families)
    gyro_name = attitude.gyro
    types = {s.name: s.type for s in spec.sensors}
    tables = {sd.name: _slim_table(mission.telemetry[sd.name], sd, types[sd.name]) for sd in sensors}
    sensors = _reachable_frames(sensors, tables, attitude)

    elements = _attitude_elements(initial_attitude(mission, attitude, mode), mode, options)
    models = {sd.name: sd.model for sd in sensors}
    for g in gyros:
        models.setdefault(g.name, make_model(g))
    if isinstance(attitude, GyroAttitude) and attitude.step_tags:  # its bias follows aux channels
        models[attitude.gyro] = GyroStepModel(models[attitude.gyro], attitude.step_tags)
    param_map = _sensor_elements(spec, models, elements, use_gyro, gyro_name)
    elements = _link_sun_sensor_tilt(spec, elements, param_map)
    state = StateVector(tuple(elements))
    unavailable = {f"{name}.{eid}": why for name, m in models.items() for eid, why in m.unavailable_effects().items()}
    state = apply_state_options(state, options, unavailable)
    return Problem(
        state=state,
        attitude=attitude,
        sensors=sensors,
        param_map=param_map,
        builder=builder,
        tables=tables,
        mode=mode,
        gyro_name=gyro_name,
        chunk_frames=max(1, int(chunk_frames)),
    )


def _attitude_provider(mission, eph, gyros: list, use_gyro: bool, chunk_frames: int, fams=None) -> AttitudeProvider:
    """SIDP's attitude provider: the spin axis (Eq 4-2) on a spinning mission, the first gyro
    carrying the attitude (seed §4.2.7, Eq 4-32, 4-38) when there is one and ``use_gyro``, else constant
    roll/pitch/yaw from the reference frame (Eq 4-6); the gyro's bias follows its ``fams`` (gyro_steps.py)."""
    spec = mission.spec
    mode = spec.attitude_mode
    if mode == "spinning":
        return SpinAttitude()
    if gyros and use_gyro:
        g = gyros[0]
        tab = mission.telemetry[g.name]
        return GyroAttitude(
            mode,
            eph,
            g.name,
            tab.t,
            tab.stack(("wx", "wy", "wz")),
            block_knots=chunk_frames,
            earth_rate=spec.earth_rate_rad_s,
            steps=gyro_step_channels(fams, g.name, tab.t, mission.aux),
        )
    return ReferenceAttitude(mode, eph)


def _reachable_frames(sensors: list[SensorData], tables: dict, attitude: AttitudeProvider) -> list[SensorData]:
    """The sensors without the frames the attitude provider cannot reach (before the first
    gyro interval); ``tables`` (sensor -> slim telemetry table) is cut to match, in place."""
    if attitude.gyro is None:
        return sensors
    kept = []
    for sd in sensors:
        m = attitude.covers(sd.t)
        if not np.all(m):
            sd = _subset(sd, m)
            tab = tables[sd.name]
            tables[sd.name] = replace(
                tab,
                t=tab.t[m],
                lines=np.asarray(tab.lines)[m],
                columns={k: np.asarray(v)[m] for k, v in tab.columns.items()},
            )
        kept.append(sd)
    return kept


def _attitude_elements(att0: Mapping[str, float], mode: str, options: StateOptions) -> list[Element]:
    """The attitude elements, solved for from ``att0``: spin-axis RA and Dec (Eq 4-2) on a
    spinning mission, else roll, pitch and yaw from the reference frame (Eq 4-6)."""
    elements: list[Element] = []
    if mode == "spinning":
        for n in RADEC:
            elements.append(
                Element(
                    n,
                    "rad",
                    SOLVE_FOR,
                    att0[n],
                    options.attitude_sigma,
                    None,
                    n.split(".")[1],
                    "attitude",
                    True,
                    "attitude",
                    "spin-axis " + ("right ascension" if n.endswith("ra") else "declination") + ", Eq 4-2",
                )
            )
    else:
        roll, pitch, yaw = (att0[n] for n in RPY)
        for spec_ in rpy_specs(roll, pitch, yaw, sigma=options.attitude_sigma):
            elements.append(_element_from_spec(None, spec_, SOLVE_FOR, kind="attitude"))
    return elements


def _sensor_elements(
    spec, models: Mapping, elements: list[Element], use_gyro: bool, gyro_name: str | None
) -> dict[str, dict[str, str]]:
    """SODL (seed §3.2.2, Table 3-1): every parameter of every sensor's model becomes an
    element of ``elements`` (extended in place) with its default role; returns the param
    map, sensor -> {local param name -> element name}. Gyros other than the one carrying
    the attitude are held."""
    param_map: dict[str, dict[str, str]] = {}
    for s in spec.sensors:
        model = models[s.name]
        pmap = {}
        amplitudes_zero = unseen_at_prior(model)
        for p in model.parameters():
            role = default_role(s.type, p, s)
            if role == SOLVE_FOR and p.name in amplitudes_zero:
                role = HELD
            if s.type == "gyro" and (not use_gyro or s.name != gyro_name):
                role = HELD
            el = _element_from_spec(s.name, p, role)
            pmap[p.name] = el.name
            names_now = [e.name for e in elements]
            if el.name not in names_now:
                elements.append(el)
            elif el.name.split(".", 1)[0] == s.name:
                # a shared element (e.g. the Sun-sensor tilt ε_S used by the horizon
                # model) takes its data-book value from the sensor that owns it
                elements[names_now.index(el.name)] = el
        param_map[s.name] = pmap
    return param_map


def _with_families(sensors, families: Mapping[str, Sequence[str]], builder) -> list[SensorData]:
    """The prepared sensors with their generic family effects (:mod:`gcs_core.models.drift`)."""
    from gcs_core.models.drift import argument_of_latitude, with_families

    def phase(t):
        r, v = builder.orbit(t)
        return argument_of_latitude(r, v)

    return [
        replace(sd, model=with_families(sd, families[sd.name], phase)) if families.get(sd.name) else sd
        for sd in sensors
    ]


def _link_sun_sensor_tilt(spec, elements: list[Element], param_map: dict) -> list[Element]:
    """ICD §5 horizon: ε_S is the plane-field Sun sensor's ``tilt`` — one element for both.

    A horizon scanner names its Sun sensor with the book key ``sun_sensor``; without it,
    a mission with exactly one plane-field Sun sensor links to that one.
    """
    pfss = [s.name for s in spec.sensors if s.type == "plane_field_sun"]
    drop = set()
    for s in spec.sensors:
        if s.type != "horizon" or "eps_S" not in param_map.get(s.name, {}):
            continue
        target = s.get("sun_sensor") or (pfss[0] if len(pfss) == 1 else None)
        if target is None or target not in param_map:
            continue
        own = param_map[s.name]["eps_S"]
        linked = param_map[target].get("tilt")
        if linked and own != linked:
            param_map[s.name]["eps_S"] = linked
            drop.add(own)
    return [e for e in elements if e.name not in drop]


def apply_state_options(
    state: StateVector, options: StateOptions, unavailable: Mapping[str, str] | None = None
) -> StateVector:
    """Roles and overrides of the config's ``[state]`` table applied to the state.

    ``unavailable`` maps an effect id this mission cannot have (``MAG.field_gradient``
    without position channels) to what it needs, for the message when one is asked for.
    """
    roles: dict[str, str] = {}
    unavailable = unavailable or {}
    for eid in options.effects:
        if eid in unavailable:
            why = unavailable[eid]
            raise ConfigError(f"effect '{eid}' is not available on this mission: it {why}", key="state.effects")
        names = _effect_elements(state, eid)
        roles.update({n: SOLVE_FOR for n in names})
    for eid in options.exclude:
        roles.update({n: HELD for n in _effect_elements(state, eid)})
    state = state.with_roles(roles)
    for name, ov in options.overrides.items():
        if name not in state:
            raise ConfigError(
                f"no state element named '{name}'{_did_you_mean(name, [e.name for e in state])}",
                key=f'state.elements."{name}"',
            )
        changes = {k: v for k, v in (("role", ov.role), ("value", ov.value), ("sigma0", ov.sigma)) if v is not None}
        state = state.replace_element(name, **changes)
    return state


def _effect_elements(state: StateVector, effect_id: str) -> list[str]:
    sensor, _, effect = effect_id.partition(".")
    names = [e.name for e in state if (e.sensor or "model") == sensor and e.effect == effect]
    if not names:
        known = sorted({f"{e.sensor or 'model'}.{e.effect}" for e in state if e.effect})
        raise ConfigError(
            f"no effect '{effect_id}' in the state definition{_did_you_mean(effect_id, known)} "
            "(see `gcs effects` for the catalogue)",
            key="state.effects",
        )
    return names


def _did_you_mean(name: str, known) -> str:
    """``; did you mean 'X'?`` for the closest known name, '' when none is close."""
    from gcs_core.suggest import did_you_mean

    return did_you_mean(name, known, cutoff=0.75)


def _subset(sd: SensorData, mask: np.ndarray) -> SensorData:
    g = sd.geom
    n = sd.n

    def cut(a):
        a = np.asarray(a)
        return a[mask] if a.ndim >= 1 and a.shape[0] == n else a

    aux = g.aux.subset(mask) if isinstance(g.aux, HeldChannels) else {k: cut(v) for k, v in g.aux.items()}
    geom = replace(
        g,
        t=g.t[mask],
        r_I=cut(g.r_I) if g.r_I is not None else None,
        v_I=cut(g.v_I) if g.v_I is not None else None,
        sun_I=cut(g.sun_I) if g.sun_I is not None else None,
        B_I=cut(g.B_I) if g.B_I is not None else None,
        star_I=cut(g.star_I) if g.star_I is not None else None,
        aux=aux,
        extra={k: cut(v) for k, v in g.extra.items()},
    )
    return replace(sd, t=sd.t[mask], y=sd.y[mask], geom=geom, lines=sd.lines[mask])


def _slim_table(tab, sd: SensorData, sensor_type: str):
    """The telemetry columns :meth:`GeometryBuilder.geometry` reads again (geometry variants):
    star catalogue positions, the horizon spin rate; the rest lives in SensorData (whose
    times and line numbers the slim table shares)."""
    keep = {"star_tracker": ("ra", "dec"), "horizon": ("spin_rate",)}.get(sensor_type, ())
    return replace(
        tab,
        t=sd.t,
        lines=sd.lines,
        columns={k: (sd.t if k == "t" else v) for k, v in tab.columns.items() if k in keep or k == "t"},
    )
