"""The contract every observation model keeps (seed §4.2, ICD §5).

A sensor model is one module holding one :class:`ObservationModel` subclass. It

* names its parameters (:class:`ParamSpec`: name, unit, data-book value, role hint),
  which SODL turns into state elements ``<SENSOR>.<name>``;
* turns a telemetry :class:`~gcs_core.io.types.Table` into measurement vectors;
* predicts the measurement **and its analytic partials together** in one call,
  vectorized over N frames: :meth:`ObservationModel.predict` returns a
  :class:`Prediction`.

Attitude partials
-----------------
Three-axis models differentiate with respect to a small body-frame rotation ``δθ``
applied to the nominal attitude, ``C_true = (I − [δθ×]) C``, so that a body vector
changes as ``δv_B = [v_B×] δθ``. The estimator chains these to whatever attitude
elements the state holds (roll/pitch/yaw by Eq 4-22, or the filter's error angles).
Spinning-mission models differentiate with respect to the three components of the
spin-axis unit vector ``Â`` in GCI (unconstrained); the chain to right ascension and
declination (Eq 4-2) is done once by the estimator.

Parameters are passed and returned by name (``dict[str, float]`` and
``dict[str, (N, m) array]``): no positional magic.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from gcs_core.io.types import SensorSpec, Table


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of an observation model.

    Attributes
    ----------
    name : local name, e.g. ``bias_x``; the state element is ``<SENSOR>.<name>``
        unless ``element`` overrides it (a parameter shared between sensors, such as
        the Sun-sensor tilt ε_S used by both the plane-field and horizon models).
    unit : internal unit of the value ("nT", "rad", "1", "s", "rad/s", "counts", ...).
    nominal : the data-book value (internal units).
    sigma : a sensible a-priori 1-sigma (internal units) when the config gives none.
    seed : True for the seed's own calibration parameters (state vectors Eq 4-13,
        4-15, 4-19, 4-26, 4-28, 4-31, 4-37); False for extended physics that the
        diagnosis catalogue offers as candidate effects.
    effect : the catalogue effect this parameter belongs to (e.g. ``"alignment"``,
        ``"scale"``, ``"bias"``, ``"time_offset"``); parameters of one effect enter
        and leave the state together.
    description : one line for humans.
    element : full element name when shared between sensors, else None.
    """

    name: str
    unit: str
    nominal: float
    sigma: float
    seed: bool = True
    effect: str = ""
    description: str = ""
    element: str | None = None


@dataclass(frozen=True)
class Geometry:
    """Everything a model needs at N frames, in GCI unless named otherwise.

    Fields a model does not need may be None. Vectors are float arrays of shape
    (N, 3); ``C_BI`` is (N, 3, 3).

    Attributes
    ----------
    t : (N,) mission seconds of each frame.
    C_BI : nominal attitude, GCI to body (three-axis missions).
    spin_axis_I : (3,) or (N, 3) spin-axis unit vector Â (spinning missions).
    r_I, v_I : spacecraft position [km] and velocity [km/s].
    sun_I : unit Sun vector from the spacecraft (corrections already applied).
    B_I : geomagnetic reference field [nT].
    star_I : unit catalog star vector of each frame's identified star (star tracker).
    omega_B : (N, 3) true body rate [rad/s] (gyro observation model).
    aux : auxiliary channels held at each frame, name -> (N,) array.
    extra : telemetry inputs that are not measurements (e.g. horizon ``spin_rate``),
        name -> (N,) array.
    ephemeris : callable ``t -> (r_I, v_I, sun_I)`` for models evaluated at shifted
        times (the horizon crossing, time-tag offsets); may be None.
    field_model : callable ``(t, r_I) -> B_I`` for models needing the field elsewhere.
    """

    t: np.ndarray
    C_BI: np.ndarray | None = None
    spin_axis_I: np.ndarray | None = None
    r_I: np.ndarray | None = None
    v_I: np.ndarray | None = None
    sun_I: np.ndarray | None = None
    B_I: np.ndarray | None = None
    star_I: np.ndarray | None = None
    omega_B: np.ndarray | None = None
    aux: Mapping[str, np.ndarray] = field(default_factory=dict)
    extra: Mapping[str, np.ndarray] = field(default_factory=dict)
    ephemeris: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
    field_model: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None

    @property
    def n(self) -> int:
        return int(np.shape(self.t)[0])


@dataclass(frozen=True)
class Prediction:
    """A model's answer at N frames: predicted measurement and partials, together.

    Attributes
    ----------
    y : (N, m) predicted measurements, telemetry units.
    d_att : (N, m, 3) partials with respect to the attitude (see module docstring);
        for the gyro model, with respect to the body rate ω.
    d_par : parameter name -> (N, m) partials, for every parameter of the model.
    valid : (N,) False where the model is undefined (Sun outside the field of view,
        no horizon crossing, ...); those frames must not be used.
    d2_par : ``(a, b)`` -> ``(component, ∂²y_c/∂a∂b)``: the second partials of the
        parameter pairs that make the model non-linear in its own parameters (a product
        such as the FSS's ``A3 sin(k tan α)``, :attr:`ObservationModel.nonlinear_pairs`),
        each in the one component it enters, as an (N,) array, a scalar or a function of
        no arguments giving one (formed when read); undefined at invalid frames. Optional;
        each unordered pair appears once. The batch uses them for Newton steps near the
        solution (:mod:`gcs_core.problem.curvature`).
    """

    y: np.ndarray
    d_att: np.ndarray
    d_par: Mapping[str, np.ndarray]
    valid: np.ndarray
    d2_par: Mapping[tuple[str, str], tuple[int, Any]] = field(default_factory=dict)


@dataclass(frozen=True)
class HeldPrediction:
    """A model's answer with its geometry held (:meth:`ObservationModel.held`), in the
    parameters of its non-linear pairs only, component by component.

    Attributes
    ----------
    y : (N, m) predicted measurements.
    d_par : name -> ``(component, ∂y_c/∂name)``, the partial (N,) or scalar of the one
        component the parameter enters.
    d2_par : ``(a, b)`` -> ``(component, ∂²y_c/∂a∂b)``, likewise.
    """

    y: np.ndarray
    d_par: Mapping[str, tuple[int, np.ndarray | float]]
    d2_par: Mapping[tuple[str, str], tuple[int, np.ndarray | float]]


class ObservationModel:
    """Base class of the seven sensor models (and any eighth).

    Subclasses set the class attributes and implement :meth:`parameters`,
    :meth:`measurements` and :meth:`predict`. They are stateless apart from the
    sensor's data-book values given at construction.
    """

    #: ICD §5 sensor type key, e.g. "magnetometer".
    type_name: ClassVar[str] = ""
    #: telemetry columns required besides ``t``.
    columns: ClassVar[tuple[str, ...]] = ()
    #: names of the m measurement components (residual axes), e.g. ("bx", "by", "bz");
    #: a class attribute, which an instance may set from its data book (the horizon scanner)
    components: tuple[str, ...] = ()
    #: unit of the measurements, for display.
    unit: ClassVar[str] = ""
    #: "three_axis", "spinning" or "rate" (the gyro: ``d_att`` is ∂y/∂ω): what the
    #: partials ``d_att`` refer to.
    attitude_kind: ClassVar[str] = "three_axis"
    #: parameter pairs whose second partials :meth:`predict` gives (``Prediction.d2_par``),
    #: the pairs that make the model non-linear in its own parameters; () for none.
    nonlinear_pairs: ClassVar[tuple[tuple[str, str], ...]] = ()
    #: parameter -> the amplitudes through which alone the data see it (e.g. a sine
    #: frequency through its amplitude); see :mod:`gcs_core.diagnosis.determination`.
    seen_through: ClassVar[Mapping[str, tuple[str, ...]]] = {}
    #: data-book keys this type knows (besides name/type/telemetry/alignment_deg/noise).
    book_keys: ClassVar[tuple[str, ...]] = ()

    def __init__(self, sensor: SensorSpec, *, aux_channels: tuple[str, ...] = ()):
        self.sensor = sensor
        self.aux_channels = tuple(aux_channels)

    @property
    def name(self) -> str:
        return self.sensor.name

    def parameters(self) -> tuple[ParamSpec, ...]:
        """All parameters of this sensor, seed ones first, then extended physics."""
        raise NotImplementedError

    def unavailable_effects(self) -> dict[str, str]:
        """Effects this type knows but this sensor lacks, each with what it would need.

        An effect whose parameters exist only under a condition of the mission or the
        physics (the magnetometer's field gradient needs a constant field and position
        channels) is named here, so asking for it says what is missing rather than
        only that the effect does not exist.
        """
        return {}

    def nominal(self) -> dict[str, float]:
        """Data-book values of every parameter, by local name."""
        return {p.name: p.nominal for p in self.parameters()}

    def sigma(self) -> np.ndarray:
        """(m,) 1-sigma measurement noise per component, telemetry units (ICD ``noise``)."""
        raise NotImplementedError

    def measurements(self, table: Table) -> tuple[np.ndarray, np.ndarray]:
        """``(t, y)``: frame times (N,) and measured values (N, m) from telemetry."""
        return table.t, table.stack(self.columns)

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """Predicted measurements and all partials at the frames of ``geom``."""
        raise NotImplementedError

    def held(
        self, geom: Geometry, params: Mapping[str, float], rows: np.ndarray | None = None
    ) -> Callable[[Mapping[str, float]], HeldPrediction] | None:
        """A fast evaluation in the :attr:`nonlinear_pairs` parameters with everything else
        held (the attitude, the ephemeris and the other parameters at ``params``): a
        function ``(params, wanted=None) -> HeldPrediction`` at the frames ``rows`` of
        ``geom`` (all by default), equal to :meth:`predict` there in ``y`` and in the
        partials of those parameters (or of the ``wanted`` ones), its residual the plain
        difference ``y − ŷ``. None: the model has none."""
        return None

    def residual(self, y_meas: np.ndarray, y_pred: np.ndarray, geom: Geometry | None = None) -> np.ndarray:
        """Measured minus predicted; models with wrapping observables override it (the
        horizon scanner wraps modulo the spin period, which it reads from ``geom``)."""
        return np.asarray(y_meas) - np.asarray(y_pred)

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "type": self.type_name, "components": self.components, "unit": self.unit}
