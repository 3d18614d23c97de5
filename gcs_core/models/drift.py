"""Generic candidate families: a sensor's drifting parameters varying with a channel.

Real sensors have parameters that physically drift: a tracker's alignment bends with its
bench temperature (thermo-elastic), a Sun sensor's offset and a magnetometer's gain follow
their electronics' temperature, anything may follow the orbit (thermal cycling) or creep
over time. For a parameter ``p`` of a sensor (an element of its alignment, bias or scale
effect) and a channel ``x(t)``, the family makes ``p`` vary linearly with the channel::

    p(t) = p + Σ_j k_j x_j(t),    y(t) = h(p(t)) ≈ h(p) + Σ_j k_j x_j(t) ∂h/∂p        (1)

with regressors ``x_j``: an aux channel minus its mean over the sensor's frames (one
column; ``k`` per unit of the channel), the orbit phase's first or second harmonic
``cos n u, sin n u`` (two columns), or time from mid-span in hours (a drift). Eq. (1) is
first order in ``k x``: the drift of a parameter is small against the range over which its
partial ``∂h/∂p`` changes (a tracker bending 20″ changes ``∂h/∂a`` by 1e-4 of itself). The
family's partials are therefore exact for the prediction (1), ``∂y/∂k_j = x_j ∂h/∂p``;
:func:`gcs_core.models.checks` style finite differences agree to round-off
(``tests/unit/test_families.py``).

A family's effect is ``<effect>_vs_<channel>`` (``alignment_vs_tam_temp``,
``bias_vs_orbit1``, ``scale_vs_time``), its elements ``<param>_vs_<channel>[_cos|_sin]``.
The wrapper :class:`DriftingModel` adds them to any model without touching it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from gcs_core.models import common
from gcs_core.models.base import Geometry, ObservationModel, ParamSpec, Prediction

#: the effects whose parameters may drift, and the fine Sun sensor's offsets counted as its bias
DRIFTING = ("alignment", "bias", "scale")
FSS_OFFSETS = ("A1", "B1")
#: family tags that are not aux channels
ORBIT_TAGS = {"orbit1": 1, "orbit2": 2}
TIME_TAG = "time"
HOUR_S = 3600.0


def argument_of_latitude(r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u`` [rad, 0..2π) from position and velocity (N, 3) (Vallado, *Fundamentals of Astrodynamics
    and Applications*, 4th ed., §2.5: argument of latitude)."""
    h = np.cross(r, v)
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    node = np.cross(np.array([0.0, 0.0, 1.0]), h)
    nn = np.linalg.norm(node, axis=1, keepdims=True)
    node = np.where(nn > 1e-12, node / np.where(nn > 0, nn, 1.0), np.array([1.0, 0.0, 0.0]))
    w = np.cross(h, node)
    return np.mod(np.arctan2(np.einsum("ij,ij->i", r, w), np.einsum("ij,ij->i", r, node)), 2 * np.pi)


def drifting_params(model: ObservationModel) -> dict[str, tuple[str, ...]]:
    """effect -> the model's parameters of that drifting effect (in model order)."""
    out: dict[str, list[str]] = {}
    for p in model.parameters():
        eff = p.effect
        if model.type_name == "fine_sun" and p.name in FSS_OFFSETS:
            eff = "bias"
        if eff in DRIFTING and p.element is None:
            out.setdefault(eff, []).append(p.name)
    return {k: tuple(v) for k, v in out.items()}


def split_family(effect: str) -> tuple[str, str] | None:
    """``(base effect, channel tag)`` of a family effect name, None for any other name."""
    base, sep, tag = effect.partition("_vs_")
    if not sep or base not in DRIFTING or not tag:
        return None
    return base, tag


def regressor_names(tag: str) -> tuple[str, ...]:
    """Suffixes of a family's columns: one for an aux channel or time, cos/sin for the orbit."""
    return ("cos", "sin") if tag in ORBIT_TAGS else ("",)


def family_regressors(tag: str, t: np.ndarray, aux: Mapping[str, np.ndarray], orbit_phase) -> np.ndarray:
    """(N, j) regressors of a family at the sensor's frames ``t`` (module docstring).

    ``orbit_phase``: a function of no arguments giving the argument of latitude at ``t``.
    """
    if tag in ORBIT_TAGS:
        u = orbit_phase()
        n = ORBIT_TAGS[tag]
        return np.column_stack([np.cos(n * u), np.sin(n * u)])
    if tag == TIME_TAG:
        return ((t - 0.5 * (t[0] + t[-1])) / HOUR_S)[:, None]
    x = np.asarray(aux[tag], dtype=float)
    return (x - float(np.mean(x)))[:, None]


def channel_unit(tag: str, unit_of_aux) -> str:
    if tag in ORBIT_TAGS:
        return "1"
    if tag == TIME_TAG:
        return "h"
    return unit_of_aux(tag)


def family_unit(unit: str, tag: str) -> str:
    """Unit of a family's coefficient on a parameter in ``unit``: the parameter's own for the
    orbit's harmonics (an amplitude), per hour for time, per °C for a channel named as a
    temperature, and per unit of the channel otherwise (aux.csv carries no units)."""
    if tag in ORBIT_TAGS:
        return unit
    if tag == TIME_TAG:
        return f"{unit}/h"
    return f"{unit}/degC" if "temp" in tag.lower() else f"{unit} per unit of {tag}"


class DriftingModel(ObservationModel):
    """A model with generic families added (module docstring); everything else is the
    wrapped model's. Made by :func:`with_families`, one subclass per wrapped type."""

    def __init__(self, inner: ObservationModel, families: Sequence[str], t: np.ndarray, X: Mapping[str, np.ndarray]):
        super().__init__(inner.sensor, aux_channels=inner.aux_channels)
        self.inner = inner
        self.components = inner.components
        self.t_frames = np.asarray(t, dtype=float)
        self.X = dict(X)  # tag -> (N, j) regressors at t_frames
        self.families = tuple(families)
        base = drifting_params(inner)
        #: family param name -> (base param, tag, column)
        self.terms: dict[str, tuple[str, str, int]] = {}
        specs = {p.name: p for p in inner.parameters()}
        extra: list[ParamSpec] = []
        for fam in self.families:
            eff, tag = split_family(fam) or ("", "")
            for pname in base.get(eff, ()):
                for j, suf in enumerate(regressor_names(tag)):
                    name = f"{pname}_vs_{tag}" + (f"_{suf}" if suf else "")
                    sp = specs[pname]
                    self.terms[name] = (pname, tag, j)
                    extra.append(
                        ParamSpec(
                            name,
                            family_unit(sp.unit, tag),
                            0.0,
                            10.0 * sp.sigma,
                            seed=False,
                            effect=fam,
                            description=f"{sp.description or pname} per unit of {tag}" + (f" ({suf})" if suf else ""),
                        )
                    )
        self._specs = tuple(inner.parameters()) + tuple(extra)

    def __getattr__(self, name: str) -> Any:
        # attributes of the wrapped model (a magnetometer's gradient flag, ...); not the
        # wrapper's own (set in __init__ before any read)
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    def parameters(self) -> tuple[ParamSpec, ...]:
        return self._specs

    def unavailable_effects(self) -> dict[str, str]:
        return self.inner.unavailable_effects()

    def sigma(self) -> np.ndarray:
        return self.inner.sigma()

    def measurements(self, table):
        return self.inner.measurements(table)

    def residual(self, y_meas, y_pred, geom=None):
        return self.inner.residual(y_meas, y_pred, geom)

    def _rows(self, t: np.ndarray) -> np.ndarray:
        """Row of each time of ``t`` among the sensor's frames (nearest)."""
        k = np.clip(np.searchsorted(self.t_frames, t), 0, len(self.t_frames) - 1)
        km = np.clip(k - 1, 0, len(self.t_frames) - 1)
        closer = np.abs(self.t_frames[km] - t) < np.abs(self.t_frames[k] - t)
        return np.where(closer, km, k)

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """The wrapped model's prediction plus the families' terms, Eq. (1)."""
        own = {k: v for k, v in params.items() if k not in self.terms}
        pred = self.inner.predict(geom, own)
        rows = self._rows(np.asarray(geom.t, dtype=float))
        y = np.array(pred.y, dtype=float)
        d_par: dict[str, common.PartialSource] = {n: (lambda n=n: pred.d_par[n]) for n in pred.d_par}
        for name, (pname, tag, j) in self.terms.items():
            x = self.X[tag][rows, j][:, None]
            k = float(params.get(name, 0.0))
            if k != 0.0:
                y += k * x * np.nan_to_num(pred.d_par[pname])
            d_par[name] = lambda x=x, pname=pname: x * pred.d_par[pname]
        return common.finish(y, pred.d_att, d_par, pred.valid, self._specs, pred.d2_par)

    def held(self, geom: Geometry, params: Mapping[str, float], rows: np.ndarray | None = None):
        """The wrapped model's fast evaluation plus the families' terms, held at ``params``
        (they are first order in drifts of parameters other than the held ones)."""
        own = {k: v for k, v in params.items() if k not in self.terms}
        inner = self.inner.held(geom, own, rows)
        if inner is None or not any(params.get(n, 0.0) != 0.0 for n in self.terms):
            return inner
        delta = self.predict(geom, params).y - self.inner.predict(geom, own).y
        delta = np.nan_to_num(delta if rows is None else delta[rows])

        fn: Any = inner  # called as (params, wanted), as ObservationModel.held documents

        def call(p: Mapping[str, float], wanted=None):
            hp = fn({k: v for k, v in p.items() if k not in self.terms}, wanted)
            return replace(hp, y=hp.y + delta)

        return call


_CLASSES: dict[type, type] = {}


def _class_for(inner: ObservationModel) -> type:
    cls = type(inner)
    if cls not in _CLASSES:
        attrs = {
            k: getattr(cls, k)
            for k in ("type_name", "columns", "unit", "attitude_kind", "nonlinear_pairs", "seen_through", "book_keys")
        }
        _CLASSES[cls] = type(f"Drifting{cls.__name__}", (DriftingModel,), attrs)
    return _CLASSES[cls]


def with_families(sd, families: Sequence[str], orbit_phase) -> ObservationModel:
    """The model of prepared sensor ``sd`` with the family effects ``families`` added
    (those this sensor has parameters and channels for). ``orbit_phase``: a function of
    ``t`` giving the argument of latitude [rad]."""
    inner = sd.model.inner if isinstance(sd.model, DriftingModel) else sd.model
    base = drifting_params(inner)
    aux = sd.geom.aux
    keep, X = [], {}
    t = np.asarray(sd.t, dtype=float)
    for fam in dict.fromkeys(families):
        parts = split_family(fam)
        if parts is None or parts[0] not in base or sd.n < 2:
            continue
        tag = parts[1]
        if tag not in ORBIT_TAGS and tag != TIME_TAG and tag not in aux:
            continue
        if tag not in X:
            X[tag] = family_regressors(tag, t, aux, lambda: orbit_phase(t))
        keep.append(fam)
    if not keep:
        return inner
    return _class_for(inner)(inner, keep, t, X)
