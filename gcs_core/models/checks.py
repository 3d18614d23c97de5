"""One finite-difference checker for the analytic partials of every observation model.

:func:`check_partials` perturbs each parameter of the model and the attitude, re-runs
:meth:`~gcs_core.models.base.ObservationModel.predict`, and compares the difference
quotient with the analytic partials of the unperturbed :class:`Prediction`, on the
frames that are valid in every prediction involved. The attitude is perturbed as
the models differentiate it (base.py):

* ``three_axis``: ``C_BI ← rotvec_to_dcm(±h e_k) C_BI``, the exact form of
  ``(I − [δθ×]) C``;
* ``spinning``: ``spin_axis_I ± h e_k`` (components, unconstrained);
* ``rate`` (gyro): ``omega_B ± h e_k``.

Schemes and their truncation errors (step ``h``, third/second derivative ``f'''``,
``f''``)::

    central:  (f(x+h) − f(x−h)) / 2h,   error h² f'''/6
    forward:  (f(x+h) − f(x)) / h,      error h f''/2

Steps: parameter ``p`` uses ``h_p = rel_step · max(|x_p|, σ_p)`` with ``σ_p`` the
parameter's a-priori sigma (its natural scale); the attitude uses ``rel_step`` rad (or
unit-vector components, or ``rel_step · max(|ω|, 1e-3 rad/s)`` for rates). Differences
of predictions go through the model's ``residual`` (given the geometry when it accepts
one), so observables that wrap (horizon times) difference correctly. Second partials
(``Prediction.d2_par``, pair ``(a, b)``) are checked as differences in ``b`` of the
analytic ``∂y/∂a``, reported as ``d2:a,b``.

An element passes when ``max |analytic − numeric| ≤ atol_p + rtol · max |analytic|
+ ROUNDOFF · max |y| / h`` (the last term is the cancellation error of the quotient).
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from gcs_core.frames.rotations import rotvec_to_dcm
from gcs_core.models import common
from gcs_core.models.base import Geometry, ObservationModel

#: relative tolerance of each scheme with the default steps (truncation + round-off).
CENTRAL_DIFFERENCE_RTOL = 1e-6
FORWARD_DIFFERENCE_RTOL = 1e-3
SCHEME_RTOL = {"central": CENTRAL_DIFFERENCE_RTOL, "forward": FORWARD_DIFFERENCE_RTOL}
#: default relative steps: near the optimum eps^(1/3) (central) and eps^(1/2) (forward).
SCHEME_STEP = {"central": 1e-5, "forward": 1e-7}
#: multiple of machine epsilon allowed for cancellation in f(x+h) − f(x−h).
ROUNDOFF = 1e3 * np.finfo(float).eps

ATTITUDE_NAMES = ("att_1", "att_2", "att_3")


@dataclass(frozen=True)
class ElementCheck:
    """Comparison for one state element (a parameter, or one attitude axis ``att_k``).

    Attributes
    ----------
    name : parameter name or ``att_1..att_3``.
    step : finite-difference step used (internal units).
    max_abs_error : max over valid frames and components of ``|analytic − numeric|``.
    max_abs_partial : max of ``|analytic|`` over the same entries (the scale).
    tolerance : the bound ``max_abs_error`` is held to.
    """

    name: str
    step: float
    max_abs_error: float
    max_abs_partial: float
    tolerance: float

    @property
    def ok(self) -> bool:
        return bool(self.max_abs_error <= self.tolerance)

    @property
    def relative_error(self) -> float:
        return float(self.max_abs_error / max(self.max_abs_partial, 1e-300))


@dataclass(frozen=True)
class CheckReport:
    """Result of :func:`check_partials`.

    Attributes
    ----------
    model : ``<type>:<sensor name>``.
    scheme : "central" or "forward".
    n_frames, n_valid : frames given, frames valid in the unperturbed prediction.
    elements : one :class:`ElementCheck` per parameter, then per attitude axis.
    """

    model: str
    scheme: str
    n_frames: int
    n_valid: int
    elements: tuple[ElementCheck, ...]

    @property
    def passed(self) -> bool:
        return self.n_valid > 0 and all(e.ok for e in self.elements)

    def failures(self) -> list[ElementCheck]:
        return [e for e in self.elements if not e.ok]

    def summary(self) -> str:
        lines = [f"{self.model} ({self.scheme}, {self.n_valid}/{self.n_frames} valid frames)"]
        for e in self.elements:
            flag = "ok " if e.ok else "BAD"
            lines.append(
                f"  {flag} {e.name:<22} err {e.max_abs_error:.3e}  tol {e.tolerance:.3e}  "
                f"|d| {e.max_abs_partial:.3e}  rel {e.relative_error:.2e}  h {e.step:.2e}"
            )
        return "\n".join(lines)


def _differ(model: ObservationModel, geom: Geometry):
    """``(a, b) -> a − b`` through the model's residual (with the geometry if it takes it)."""
    if "geom" in inspect.signature(model.residual).parameters:
        return lambda a, b: np.asarray(model.residual(a, b, geom=geom))
    return lambda a, b: np.asarray(model.residual(a, b))


def _attitude_perturbations(model: ObservationModel, geom: Geometry, rel_step: float):
    """Step and ``(geom_plus, geom_minus)`` builders for the three attitude axes."""
    kind = model.attitude_kind
    n = geom.n
    if kind == "three_axis":
        h = rel_step

        def make(k, sign):
            phi = np.zeros((n, 3))
            phi[:, k] = sign * h
            return dataclasses.replace(geom, C_BI=rotvec_to_dcm(phi) @ np.asarray(geom.C_BI, dtype=float))
    elif kind == "spinning":
        h = rel_step
        base = np.array(np.broadcast_to(np.asarray(geom.spin_axis_I, dtype=float), (n, 3)))

        def make(k, sign):
            a = base.copy()
            a[:, k] += sign * h
            return dataclasses.replace(geom, spin_axis_I=a)
    elif kind == "rate":
        base = np.array(np.broadcast_to(np.asarray(geom.omega_B, dtype=float), (n, 3)))
        h = rel_step * max(float(np.max(np.abs(base))), 1e-3)

        def make(k, sign):
            w = base.copy()
            w[:, k] += sign * h
            return dataclasses.replace(geom, omega_B=w)
    else:
        raise ValueError(f"unknown attitude_kind {kind!r}")
    return h, make


def check_partials(
    model: ObservationModel,
    geom: Geometry,
    params: Mapping[str, float] | None = None,
    *,
    rel_step: float | None = None,
    scheme: str = "central",
    rtol: float | None = None,
    atol_by_param: Mapping[str, float] | None = None,
) -> CheckReport:
    """Compare the analytic partials of ``model.predict(geom, params)`` with finite differences.

    Parameters
    ----------
    model, geom, params : as for ``predict``; missing parameters take their nominal value.
    rel_step : relative step (module docstring); default per scheme (``SCHEME_STEP``).
    scheme : "central" or "forward".
    rtol : relative tolerance; default per scheme (``SCHEME_RTOL``).
    atol_by_param : absolute tolerance per element name (parameter or ``att_k``), default 0.

    Returns
    -------
    CheckReport with one entry per parameter and attitude axis.
    """
    if scheme not in SCHEME_RTOL:
        raise ValueError(f"scheme must be one of {tuple(SCHEME_RTOL)}")
    rel_step = SCHEME_STEP[scheme] if rel_step is None else rel_step
    rtol = SCHEME_RTOL[scheme] if rtol is None else rtol
    atol_by_param = dict(atol_by_param or {})
    specs = model.parameters()
    values = {p.name: float(p.nominal) for p in specs}
    values.update({k: float(v) for k, v in (params or {}).items()})
    base = model.predict(geom, values)
    diff = _differ(model, geom)
    y_scale = float(np.max(np.abs(base.y[base.valid]), initial=0.0))

    def compare(name, step, analytic, run, base_y=None, sub=diff):
        plus = run(+1)
        if scheme == "central":
            minus = run(-1)
            ok = base.valid & plus.valid & minus.valid
            numeric = sub(plus.y, minus.y) / (2.0 * step)
        else:
            ok = base.valid & plus.valid
            numeric = sub(plus.y, base.y if base_y is None else base_y) / step
        a, d = analytic[ok], numeric[ok]
        err = float(np.max(np.abs(a - d), initial=0.0))
        scale = float(np.max(np.abs(a), initial=0.0))
        tol = atol_by_param.get(name, 0.0) + rtol * scale + ROUNDOFF * y_scale / step
        if not np.any(ok):
            err = np.inf
        return ElementCheck(name, step, err, scale, tol)

    elements = []
    steps = {p.name: rel_step * max(abs(values[p.name]), abs(p.sigma)) for p in specs}
    for p in specs:

        def run(sign, _name=p.name, _x=values[p.name], _h=steps[p.name]):
            return model.predict(geom, {**values, _name: _x + sign * _h})

        elements.append(compare(p.name, steps[p.name], np.asarray(base.d_par[p.name]), run))

    for a, b in base.d2_par:  # second partials: differences of ∂y/∂a in b

        def run2(sign, _a=a, _b=b):
            pr = model.predict(geom, {**values, _b: values[_b] + sign * steps[_b]})
            return dataclasses.replace(pr, y=np.asarray(pr.d_par[_a]))

        c, v = common.component_values(base.d2_par[(a, b)], geom.n)
        analytic = np.zeros_like(base.y)
        analytic[:, c] = v
        elements.append(
            compare(f"d2:{a},{b}", steps[b], analytic, run2, base_y=np.asarray(base.d_par[a]), sub=np.subtract)
        )

    h_att, make = _attitude_perturbations(model, geom, rel_step)
    for k, name in enumerate(ATTITUDE_NAMES):

        def run_att(sign, _k=k):
            return model.predict(make(_k, sign), values)

        elements.append(compare(name, h_att, np.asarray(base.d_att)[..., k], run_att))

    return CheckReport(
        model=f"{model.type_name}:{model.name}",
        scheme=scheme,
        n_frames=geom.n,
        n_valid=int(np.count_nonzero(base.valid)),
        elements=tuple(elements),
    )


def assert_partials_match(
    model: ObservationModel, geom: Geometry, params: Mapping[str, float] | None = None, **kwargs
) -> CheckReport:
    """:func:`check_partials`, raising ``AssertionError`` with the report if any element fails."""
    report = check_partials(model, geom, params, **kwargs)
    if not report.passed:
        raise AssertionError("analytic partials disagree with finite differences:\n" + report.summary())
    return report
