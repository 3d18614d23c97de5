"""State elements with names, units and roles (the seed's SODL, §3.2.2 and Table 3-1).

Choosing observation and transition models defines the state vector: every model
parameter becomes an element ``<SENSOR>.<param>`` and the attitude contributes its own
elements. Each element has a *role*:

* ``solve-for`` — estimated;
* ``consider`` — not estimated, but its a-priori uncertainty is carried into the
  covariance of the solve-for elements (a consider covariance);
* ``held`` — fixed at its value, no uncertainty carried.

Nothing downstream indexes the state positionally by convention: every index comes
from :meth:`StateVector.index`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from gcs_core.errors import ConfigError

#: element roles (Table 3-1): estimated, carried as a consider covariance, fixed
SOLVE_FOR = "solve-for"
CONSIDER = "consider"
HELD = "held"
ROLES = (SOLVE_FOR, CONSIDER, HELD)


@dataclass(frozen=True)
class Element:
    """One state element.

    Attributes
    ----------
    name : unique dotted name, ``<SENSOR>.<param>`` or ``att.<axis>``.
    unit : internal unit of ``value`` and ``sigma0``.
    role : one of ``solve-for``, ``consider``, ``held``.
    value : initial (a-priori) value, internal units; data-book value by default.
    sigma0 : a-priori 1-sigma, internal units; ``inf`` means no prior information.
    sensor : owning sensor name, or ``None`` for attitude / mission-wide elements.
    param : the model's local parameter name (``bias_x``); equals the tail of ``name``.
    effect : catalogue effect the element belongs to (``bias``, ``alignment`` ...).
    seed : True for the seed's own calibration parameters.
    kind : ``attitude``, ``sensor`` or ``model``.
    description : one line for humans.
    """

    name: str
    unit: str
    role: str
    value: float
    sigma0: float
    sensor: str | None = None
    param: str = ""
    effect: str = ""
    seed: bool = True
    kind: str = "sensor"
    description: str = ""

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ConfigError(
                f"role must be one of {', '.join(ROLES)}, not '{self.role}'", key=f"state.{self.name}.role"
            )


@dataclass(frozen=True)
class StateVector:
    """An ordered, named set of elements; the only source of indices.

    The order is: attitude elements first, then sensors in mission order, each
    sensor's parameters in model order. Held elements stay in the vector (their value
    is used by the models) but take no column in the estimator.
    """

    elements: tuple[Element, ...]
    _index: Mapping[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        idx = {}
        for i, e in enumerate(self.elements):
            if e.name in idx:
                raise ConfigError(f"state element '{e.name}' is defined twice", key=f"state.{e.name}")
            idx[e.name] = i
        object.__setattr__(self, "_index", idx)

    # --- lookup -----------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.elements)

    def __iter__(self):
        return iter(self.elements)

    def __contains__(self, name: str) -> bool:
        return name in self._index

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise ConfigError(f"no state element named '{name}'", key=f"state.{name}") from None

    def __getitem__(self, name: str) -> Element:
        return self.elements[self.index(name)]

    @property
    def names(self) -> list[str]:
        return [e.name for e in self.elements]

    def with_role(self, role: str) -> list[str]:
        return [e.name for e in self.elements if e.role == role]

    @property
    def solve_for(self) -> list[str]:
        return self.with_role(SOLVE_FOR)

    @property
    def consider(self) -> list[str]:
        return self.with_role(CONSIDER)

    def values(self) -> dict[str, float]:
        return {e.name: e.value for e in self.elements}

    def sensor_params(self, sensor: str, values: Mapping[str, float] | None = None) -> dict[str, float]:
        """Local-name -> value for one sensor's elements (what a model's ``predict`` takes)."""
        vals = values if values is not None else self.values()
        return {e.param: vals[e.name] for e in self.elements if e.sensor == sensor}

    # --- edits (return new vectors; the state is immutable) ----------------------
    def replace_element(self, name: str, **changes) -> StateVector:
        i = self.index(name)
        elems = list(self.elements)
        elems[i] = replace(elems[i], **changes)
        return StateVector(tuple(elems))

    def with_roles(self, roles: Mapping[str, str]) -> StateVector:
        out = self
        for name, role in roles.items():
            out = out.replace_element(name, role=role)
        return out

    def with_values(self, values: Mapping[str, float]) -> StateVector:
        elems = [replace(e, value=float(values[e.name])) if e.name in values else e for e in self.elements]
        return StateVector(tuple(elems))

    def effect_elements(self, sensor: str | None, effect: str) -> list[str]:
        return [e.name for e in self.elements if e.sensor == sensor and e.effect == effect]

    def table(self) -> list[dict]:
        """Rows for reports and screens."""
        return [
            {
                "name": e.name,
                "unit": e.unit,
                "role": e.role,
                "value": e.value,
                "sigma0": e.sigma0,
                "effect": e.effect,
                "seed": e.seed,
            }
            for e in self.elements
        ]


def prior_covariance(state: StateVector, names: Sequence[str]) -> np.ndarray:
    """Diagonal a-priori covariance of ``names`` (``inf`` sigmas give zero information)."""
    return np.diag([state[n].sigma0 ** 2 for n in names])


def prior_information(state: StateVector, names: Sequence[str]) -> np.ndarray:
    """Diagonal a-priori information ``P0⁻¹`` of ``names``; ``sigma0 = inf`` gives 0."""
    s = np.array([state[n].sigma0 for n in names], dtype=float)
    with np.errstate(divide="ignore"):
        info = np.where(np.isfinite(s) & (s > 0), 1.0 / np.where(s > 0, s, 1.0) ** 2, 0.0)
    return np.diag(info)


def merge_states(parts: Iterable[Iterable[Element]]) -> StateVector:
    """Concatenate element lists, keeping the first definition of shared elements."""
    seen: dict[str, Element] = {}
    for part in parts:
        for e in part:
            seen.setdefault(e.name, e)
    return StateVector(tuple(seen.values()))
