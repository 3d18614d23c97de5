"""Earth horizon scanner on a spinner, seed §4.2.1, Eq 4-12 and 4-13; ICD §5 ``horizon``.

Observables: ``dt_in``, ``dt_out`` [s], the times from the Sun sighting (telemetry ``t``)
to the horizon-in and horizon-out crossings, at the measured spin rate ``ω``
(``geom.extra["spin_rate"]`` [rad/s]). The model is the ICD's reading of Eq 4-12.
At the crossing time ``τ = t + dt + Δt`` (``Δt``: orbit in-track time error; the
ephemeris ``(r, v, Ŝ) = geom.ephemeris(τ)`` is read there), with ``Ê = −r/|r|``::

    ρ  = asin(R(φ_T)/|r|)  (the horizon at the tangent point, below),   ρ' = ρ + Δρ,
    γ' = γ + Δγ,   η = acos(Â·Ê)
    M̂ = Â × Ê / sin η,   N̂ = Ê × M̂
    cos Λ = (cos γ' − cos ρ' cos η) / (sin ρ' sin η),   sin Λ = ∓sqrt(1 − cos²Λ)  (− in, + out)
    Ĥ = cos ρ' Ê + sin ρ' (M̂ sin Λ + N̂ cos Λ)                               (Eq 4-12c)
    Φ = atan2(Â·(Ŝ × Ĥ), Ŝ·Ĥ − (Ŝ·Â)(Ĥ·Â))                                   (Eq 4-12b)
    Ψ = Φ − Φ_H − ΔΦ − ΔΦ_S + ΔΦ_H,  ΔΦ_S = asin(cot β tan ε_S),  ΔΦ_H = asin(cot γ' tan ε_H)
    dt = (Ψ(t + dt + Δt) mod 2π) / ω                                            (Eq 4-12a)

The equation is implicit in ``dt`` (the geometry is read at the crossing). It is solved
by fixed-point iteration on the circle, ``dt ← dt + wrap(Ψ(t + dt + Δt) − ω dt)/ω``,
which contracts by ``|∂Ψ/∂τ|/ω`` (orbit rate over spin rate) per step. The partials
follow by implicit differentiation: with ``f(dt, x) = Ψ/ω``,
``d dt/dx = f_x / (1 − f_dt) = Ψ_x / (ω − Ψ_τ)``, where ``Ψ_τ = Ψ_r·v + Ψ_Ŝ·Ŝ̇``
(``Ŝ̇`` from a ±1 s central difference of the ephemeris). The derivatives of Φ are
carried forward-mode through the construction above (tangents with respect to Â, r,
Ŝ, γ', ρ'), which is the seed's chain of ∂Ĥ/∂x_i (after Eq 4-13) written once.

State (Eq 4-13): ``d_gamma`` (Δγ), ``d_rho`` (Δρ), ``d_phi`` (ΔΦ), ``eps_S`` (ε_S, the
tilt of the Sun sensor that starts the timing, shared with that sensor's ``tilt``:
``element = "<sun_sensor>.tilt"`` when the data book names ``sun_sensor``), ``eps_H``
(ε_H), ``d_t`` (Δt). Extended: ``horizon_height`` (Δh_H [km]) and ``oblateness`` (κ,
nominal 0, a flattening beyond the physics' in units of the WGS-84 f).

The Earth (``docs/horizon.md``). The horizon is the ellipsoid of semi-axes
``a = R_E + h_H + Δh_H`` and ``b = R_E (1 − f_geo − κ f) + h_H + Δh_H``, where ``f_geo`` is
the flattening the geometry carries (``geom.extra["earth_flattening"]``: WGS-84 with the
physics option ``earth_oblateness``, 0 for the ICD's sphere). The ray of nadir angle ρ
towards the horizontal direction ``ŵ`` of a crossing (``Ĥ = cos ρ Ê + sin ρ ŵ``) comes
closest to the Earth's centre in the direction ``T̂ = sin ρ r̂ + cos ρ ŵ``, the tangent
point, at geocentric latitude ``sin φ_T = T̂_z``. To first order in f it grazes the
ellipsoid when ``|r| sin ρ = R(φ_T)``, ``R(φ) = a (1 + e sin²φ)^(−1/2)``, ``e = (a/b)² − 1``.
So Eq 4-12c takes ``ρ = asin(R(φ_T)/|r|)``, each crossing at its own tangent point, found
in :data:`TANGENT_PASSES` passes from the sphere of radius ``a`` (``ρ₀ → ŵ₀ → φ_T → ρ₁ →
ŵ₁ → φ_T → ρ₂``): within 0.15 σ of an exact ray–ellipsoid crossing at every orbit for the
1.5 ms scanners (``tests/unit/test_horizon_oblate.py``), where one pass leaves up to 1 σ, the
radius at the sub-satellite latitude up to 100 σ (RMS 1–7 σ) and the sphere up to 36 σ.
Tangents over ``(Â, r, Ŝ, γ', Δρ, Δh_H, κ)`` are carried through every pass.

The attitude partials are with respect to the components of Â (normalized inside; the
gradient is tangent to the sphere). Residuals are wrapped into ``(−π/ω, π/ω]``.
With data-book ``observable = "width_midscan"`` the two components become the Earth
width ``(dt_out − dt_in) mod P`` and the mid-scan time ``dt_in + width/2 (mod P)``,
``P = 2π/ω``, with noise ``σ√2`` and ``σ/√2`` (uncorrelated for equal in/out noise).

References
----------
Wertz (ed.) 1978, §7.1–7.2 and §12.2 (horizon sensor geometry); seed Reference 6.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from gcs_core import units
from gcs_core.errors import InputError
from gcs_core.io.types import SensorSpec, Table
from gcs_core.models import common
from gcs_core.models.base import Geometry, ObservationModel, ParamSpec, Prediction

TWO_PI = 2.0 * np.pi
FLATTENING = 1.0 / 298.257223563  # WGS-84 (NIMA TR8350.2, 3rd ed., 2000, Table 3.1)
SUN_RATE_STEP_S = 1.0  # central-difference step for Ŝ̇ [s]
MAX_ITERATIONS = 30
TOLERANCE_S = 1e-12
OBSERVABLES = ("in_out", "width_midscan")
SEED_NAMES = ("d_gamma", "d_rho", "d_phi", "eps_S", "eps_H", "d_t")
K_TANGENTS = 11  # Â(3), r(3), Ŝ(3), γ', ρ'
#: passes from the spherical horizon to the tangent point's (module docstring)
TANGENT_PASSES = 2
# tangents carried through the horizon radius, X = (Â, r, Ŝ, γ', Δρ, Δh_H, κ)
NX = 13
IX_A, IX_R, IX_S, IX_G, IX_DRHO, IX_H, IX_K = slice(0, 3), slice(3, 6), slice(6, 9), 9, 10, 11, 12
E_DRHO = np.eye(NX)[IX_DRHO]


def wrap_period(x, period):
    """``x`` wrapped into ``(−period/2, period/2]``."""
    return x - period * np.ceil(x / period - 0.5)


def _vdot(u, du):
    """``u · du_k`` for vector u (N, 3) and tangents du (N, K, 3) -> (N, K)."""
    return np.einsum("ni,nki->nk", u, du)


def crossing_direction(A, r, S, gamma_p, rho_p, sign):
    """Φ of Eq 4-12b without tangents (the fixed-point iterations): phi (N,), ok (N,),
    w (N, 3); the same construction as :func:`crossing_phase`."""
    n = A.shape[0]
    rn = np.linalg.norm(r, axis=1)
    E = -r / rn[:, None]
    c = np.einsum("ni,ni->n", A, E)
    s = np.sqrt(1.0 - c**2)
    m = np.cross(A, E) / s[:, None]
    nv = (A - c[:, None] * E) / s[:, None]
    cr, sr = np.cos(rho_p) * np.ones(n), np.sin(rho_p) * np.ones(n)
    cL = (np.cos(gamma_p) - cr * c) / (sr * s)
    ok = (np.abs(cL) < 1.0) & (s > 0.0)
    w = m * (sign * np.sqrt(1.0 - cL**2))[:, None] + nv * cL[:, None]
    H = cr[:, None] * E + sr[:, None] * w
    Y = np.einsum("ni,ni->n", A, np.cross(S, H))
    X = np.einsum("ni,ni->n", S, H) - np.einsum("ni,ni->n", S, A) * np.einsum("ni,ni->n", H, A)
    return np.arctan2(Y, X), ok, w


def crossing_phase(A, r, S, gamma_p, rho_p, sign):
    """Φ of Eq 4-12b and its forward-mode tangents.

    Parameters
    ----------
    A, r, S : (N, 3) unit spin axis, position [km], unit Sun vector.
    gamma_p, rho_p : scalar or (N,) cone half angle γ' and Earth angular radius ρ' [rad].
    sign : −1 for horizon-in, +1 for horizon-out.

    Returns
    -------
    phi (N,), dphi (N, 11) with respect to (A, r, S, γ', ρ') in that order, ok (N,),
    w (N, 3) the unit horizontal direction of the crossing about Ê
    (``Ĥ = cos ρ' Ê + sin ρ' ŵ``), dw (N, 11, 3) its tangents.
    """
    n = A.shape[0]
    eye = np.broadcast_to(np.eye(3), (n, 3, 3))
    rn = np.linalg.norm(r, axis=1)
    E = -r / rn[:, None]
    dA = np.zeros((n, K_TANGENTS, 3))
    dE = np.zeros((n, K_TANGENTS, 3))
    dS = np.zeros((n, K_TANGENTS, 3))
    dA[:, 0:3, :] = eye
    dE[:, 3:6, :] = -(eye - np.einsum("ni,nj->nij", E, E)) / rn[:, None, None]
    dS[:, 6:9, :] = eye
    dg = np.zeros((n, K_TANGENTS))
    dg[:, 9] = 1.0
    dr = np.zeros((n, K_TANGENTS))
    dr[:, 10] = 1.0
    # η: nadir angle of the spin axis
    c = np.einsum("ni,ni->n", A, E)
    dc = _vdot(E, dA) + _vdot(A, dE)
    s = np.sqrt(1.0 - c**2)
    ds = -c[:, None] * dc / s[:, None]
    # M̂ = Â×Ê/sin η,  N̂ = Ê×M̂ = (Â − cos η Ê)/sin η
    m = np.cross(A, E) / s[:, None]
    dm = (np.cross(dA, E[:, None, :]) + np.cross(A[:, None, :], dE)) / s[:, None, None] - m[:, None, :] * (
        ds / s[:, None]
    )[:, :, None]
    nv = (A - c[:, None] * E) / s[:, None]
    dn = (dA - dc[:, :, None] * E[:, None, :] - c[:, None, None] * dE) / s[:, None, None] - nv[:, None, :] * (
        ds / s[:, None]
    )[:, :, None]
    # Λ: azimuth of the crossing about Ê
    cg, sg = np.cos(gamma_p) * np.ones(n), np.sin(gamma_p) * np.ones(n)
    cr, sr = np.cos(rho_p) * np.ones(n), np.sin(rho_p) * np.ones(n)
    num = cg - cr * c
    dnum = -sg[:, None] * dg + (sr * c)[:, None] * dr - cr[:, None] * dc
    den = sr * s
    dden = (cr * s)[:, None] * dr + sr[:, None] * ds
    cL = num / den
    dcL = (dnum - cL[:, None] * dden) / den[:, None]
    ok = (np.abs(cL) < 1.0) & (s > 0.0)
    sL = sign * np.sqrt(1.0 - cL**2)
    dsL = -cL[:, None] * dcL / sL[:, None]
    # Ĥ = cos ρ' Ê + sin ρ' (M̂ sin Λ + N̂ cos Λ)
    w = m * sL[:, None] + nv * cL[:, None]
    dw = (
        dm * sL[:, None, None]
        + m[:, None, :] * dsL[:, :, None]
        + dn * cL[:, None, None]
        + nv[:, None, :] * dcL[:, :, None]
    )
    H = cr[:, None] * E + sr[:, None] * w
    dH = (
        -(sr[:, None] * dr)[:, :, None] * E[:, None, :]
        + cr[:, None, None] * dE
        + (cr[:, None] * dr)[:, :, None] * w[:, None, :]
        + sr[:, None, None] * dw
    )
    # Φ = atan2(Y, X)
    SxH = np.cross(S, H)
    Y = np.einsum("ni,ni->n", A, SxH)
    dY = _vdot(SxH, dA) + _vdot(np.cross(H, A), dS) + _vdot(np.cross(A, S), dH)
    sa = np.einsum("ni,ni->n", S, A)
    ha = np.einsum("ni,ni->n", H, A)
    X = np.einsum("ni,ni->n", S, H) - sa * ha
    dX = (
        _vdot(H, dS)
        + _vdot(S, dH)
        - (_vdot(A, dS) + _vdot(S, dA)) * ha[:, None]
        - sa[:, None] * (_vdot(A, dH) + _vdot(H, dA))
    )
    phi = np.arctan2(Y, X)
    dphi = (X[:, None] * dY - Y[:, None] * dX) / (X**2 + Y**2)[:, None]
    return phi, dphi, ok, w, dw


def _lift(d, drho_p):
    """Tangents over (Â, r, Ŝ, γ', ρ') (N, 11[, ...]) to tangents over X (N, 13[, ...]),
    with ``ρ' = ρ'(X)`` of tangents ``drho_p`` (N, 13)."""
    out = np.zeros(d.shape[:1] + (NX,) + d.shape[2:])
    out[:, :10] = d[:, :10]
    extra = (1,) * (d.ndim - 2)
    out += d[:, 10].reshape(d.shape[:1] + (1,) + d.shape[2:]) * drho_p.reshape(drho_p.shape + extra)
    return out


def _limb_angle(R, dR, rn, rhat):
    """``ρ = asin(R/|r|)`` (N,) and its tangents over X (N, 13), from R (N,) and dR (N, 13)."""
    x = R / rn
    c = np.sqrt(1.0 - x**2)
    d = dR / (rn * c)[:, None]
    d[:, IX_R] -= (x / (rn * c))[:, None] * rhat
    return np.arcsin(x), d


def _ellipsoid_radius(s, ds, a, b, da, db):
    """Radius of the ellipsoid of semi-axes (a, a, b) at geocentric latitude φ, ``s = sin φ``:
    ``R = a b / sqrt(b² cos²φ + a² sin²φ) = a (1 + e s²)^(−1/2)``, ``e = (a/b)² − 1``.

    Returns R (N,) and its tangents over X (N, 13) from ds (N, 13) and da, db (13,).
    """
    e = (a / b) ** 2 - 1.0
    de = 2.0 * a / b**2 * da - 2.0 * a**2 / b**3 * db
    u = 1.0 + e * s**2
    R = a / np.sqrt(u)
    dR = (1.0 / np.sqrt(u))[:, None] * da[None, :] - (0.5 * a * u**-1.5)[:, None] * (
        (s**2)[:, None] * de[None, :] + (2.0 * e * s)[:, None] * ds
    )
    return R, dR


class HorizonModel(ObservationModel):
    """Horizon scanner on a spinner, Eq 4-12: ``dt = ((Φ − Φ_H − ΔΦ − ΔΦ_S + ΔΦ_H) mod 2π)/ω``."""

    type_name = "horizon"
    columns = ("spin_rate", "dt_in", "dt_out")
    components = ("dt_in", "dt_out")
    unit = "s"
    attitude_kind = "spinning"
    book_keys = ("gamma_deg", "phi_h_deg", "horizon_height_km", "sun_sensor", "observable")
    #: parameters the data see only in one combination (:mod:`gcs_core.diagnosis.aliases`)
    aliases = {
        ("d_phi", "eps_H"): "only ΔΦ − asin(cot γ' tan ε_H) enters the timing (Eq 4-12a, e): "
        "a constant azimuth either way, so one of the two is set by its a priori"
    }

    def __init__(self, sensor: SensorSpec, *, aux_channels: tuple[str, ...] = ()):
        super().__init__(sensor, aux_channels=aux_channels)
        obs = sensor.get("observable", "in_out")
        if obs not in OBSERVABLES:
            raise InputError(
                f"'observable' must be one of {OBSERVABLES}, got {obs!r}", key=common.book_key(sensor, "observable")
            )
        self.observable = obs
        if obs == "width_midscan":
            self.components = ("width", "midscan")
        self.gamma = self._required("gamma_deg") * units.DEG
        self.phi_h = self._required("phi_h_deg") * units.DEG
        self.h_km = self._required("horizon_height_km")
        sun = sensor.get("sun_sensor", None)
        self.sun_sensor = None if sun is None else str(sun)

    def _required(self, key: str) -> float:
        value = common.book_scalar(self.sensor, key)
        if value is None:
            raise InputError(
                f"horizon sensor '{self.name}' needs data-book key '{key}'", key=common.book_key(self.sensor, key)
            )
        return value

    def parameters(self) -> tuple[ParamSpec, ...]:
        deg = units.DEG
        tilt_element = None if self.sun_sensor is None else f"{self.sun_sensor}.tilt"
        return (
            ParamSpec(
                "d_gamma",
                "rad",
                0.0,
                0.5 * deg,
                effect="d_gamma",
                description="scanner mounting (cone) angle bias Δγ (Eq 4-12c)",
            ),
            ParamSpec(
                "d_rho", "rad", 0.0, 0.5 * deg, effect="d_rho", description="Earth angular radius bias Δρ (Eq 4-12c)"
            ),
            ParamSpec(
                "d_phi",
                "rad",
                0.0,
                0.5 * deg,
                effect="d_phi",
                description="azimuth bias ΔΦ: mounting error or electronic delay (Eq 4-12a)",
            ),
            ParamSpec(
                "eps_S",
                "rad",
                0.0,
                0.5 * deg,
                effect="tilt",
                element=tilt_element,
                description="Sun sensor plane tilt ε_S (Eq 4-12d)",
            ),
            ParamSpec(
                "eps_H", "rad", 0.0, 0.5 * deg, effect="eps_H", description="horizon sensor plane tilt ε_H (Eq 4-12e)"
            ),
            ParamSpec("d_t", "s", 0.0, 1.0, effect="d_t", description="orbit in-track time error Δt (Eq 4-13)"),
            ParamSpec(
                "horizon_height",
                "km",
                0.0,
                5.0,
                seed=False,
                effect="horizon_height",
                description="horizon (CO2 layer) height error Δh_H",
            ),
            ParamSpec(
                "oblateness",
                "1",
                0.0,
                1.0,
                seed=False,
                effect="oblateness",
                description="flattening beyond the physics' in units of WGS-84 f (κ)",
            ),
        )

    def sigma(self) -> np.ndarray:
        s = common.noise_value(self.sensor)
        if self.observable == "width_midscan":
            return np.array([s * np.sqrt(2.0), s / np.sqrt(2.0)])
        return np.array([s, s])

    def measurements(self, table: Table) -> tuple[np.ndarray, np.ndarray]:
        y = table.stack(("dt_in", "dt_out"))
        if self.observable == "width_midscan":
            period = TWO_PI / np.asarray(table.columns["spin_rate"], dtype=float)
            width = np.mod(y[:, 1] - y[:, 0], period)
            y = np.column_stack([width, np.mod(y[:, 0] + 0.5 * width, period)])
        return table.t, y

    def residual(self, y_meas, y_pred, geom: Geometry | None = None):
        """Measured minus predicted, wrapped into ``(−π/ω, π/ω]`` when ``geom`` gives ω.

        Without ``geom`` (no spin rate known) the plain difference is returned.
        """
        d = np.asarray(y_meas, dtype=float) - np.asarray(y_pred, dtype=float)
        if geom is None or "spin_rate" not in geom.extra:
            return d
        period = TWO_PI / np.asarray(geom.extra["spin_rate"], dtype=float)
        return wrap_period(d, period.reshape((-1,) + (1,) * (d.ndim - 1)))

    # ----------------------------------------------------------------------------------
    def flattening(self, geom: Geometry):
        """The Earth's flattening the geometry carries (physics option ``earth_oblateness``:
        WGS-84 when on, 0 when off); WGS-84 when the geometry does not say."""
        return geom.extra.get("earth_flattening", FLATTENING)

    def _psi(self, p, A, t_eph, eph, sign, want_partials, f_geo=FLATTENING):
        """Ψ (N,) at ephemeris time ``t_eph``; with partials, a dict of ∂Ψ and the ok mask.

        ``f_geo``: the flattening the physics carries; the horizon is the ellipsoid of
        semi-axes ``a = R_E + h_H + Δh_H`` and ``b = R_E (1 − f_geo − κ f) + h_H + Δh_H``.
        """
        r, v, S = (np.asarray(x, dtype=float) for x in eph(t_eph))
        n = r.shape[0]
        a = units.R_EARTH_KM + self.h_km + p["horizon_height"]
        b = units.R_EARTH_KM * (1.0 - f_geo - p["oblateness"] * FLATTENING) + self.h_km + p["horizon_height"]
        da = np.zeros(NX)
        da[IX_H] = 1.0
        db = da.copy()
        db[IX_K] = -units.R_EARTH_KM * FLATTENING
        q = np.einsum("ni,ni->n", r, r)
        rn = np.sqrt(q)
        rhat = r / rn[:, None]
        gamma_p = self.gamma + p["d_gamma"]
        ok = np.ones(n, dtype=bool)
        # spherical start: the equatorial radius a (Eq 4-12c, ICD), its tangents over X
        rho, drho = _limb_angle(a * np.ones(n), np.zeros((n, NX)) + da, rn, rhat)
        drhat_z = (np.eye(3)[2][None, :] - rhat[:, 2:3] * rhat) / rn[:, None]
        for _ in range(TANGENT_PASSES):
            # the crossing on the current horizon, and the tangent point it touches
            rho_p, drho_p = rho + p["d_rho"], drho + E_DRHO
            if want_partials:
                _, _, ok_k, w, dw = crossing_phase(A, r, S, gamma_p, rho_p, sign)
            else:
                _, ok_k, w = crossing_direction(A, r, S, gamma_p, rho_p, sign)
            ok &= ok_k
            cr, sr = np.cos(rho), np.sin(rho)
            s_lat = sr * rhat[:, 2] + cr * w[:, 2]  # sin φ_T, T̂ = sin ρ r̂ + cos ρ ŵ
            if want_partials:
                ds_lat = (cr * rhat[:, 2] - sr * w[:, 2])[:, None] * drho + cr[:, None] * _lift(dw[:, :, 2], drho_p)
                ds_lat[:, IX_R] += sr[:, None] * drhat_z
            else:
                ds_lat = np.zeros((n, NX))
            R, dR = _ellipsoid_radius(s_lat, ds_lat, a, b, da, db)
            rho, drho = _limb_angle(R, dR, rn, rhat)
        rho_p, drho_p = rho + p["d_rho"], drho + E_DRHO
        if want_partials:
            phi, dphi, ok_k, _, _ = crossing_phase(A, r, S, gamma_p, rho_p, sign)
        else:
            phi, ok_k, _ = crossing_direction(A, r, S, gamma_p, rho_p, sign)
        ok &= ok_k
        cb = np.einsum("ni,ni->n", A, S)
        sb = np.sqrt(1.0 - cb**2)
        tS, tH = np.tan(p["eps_S"]), np.tan(p["eps_H"])
        qS = cb / sb * tS
        qH = tH / np.tan(gamma_p)
        psi = phi - self.phi_h - p["d_phi"] - np.arcsin(qS) + np.arcsin(qH)
        ok &= (np.abs(qS) < 1.0) & (np.abs(qH) < 1.0) & (sb > 0.0) & (rn > a)
        if not want_partials:
            return psi, ok
        dphi_x = _lift(dphi, drho_p)
        rS, rH = np.sqrt(1.0 - qS**2), np.sqrt(1.0 - qH**2)
        dS_dcb = tS / (sb**3 * rS)  # ∂ΔΦ_S/∂(Â·Ŝ)
        dH_dgamma = -tH / (np.sin(gamma_p) ** 2 * rH)  # ∂ΔΦ_H/∂γ'
        d = {
            "A": dphi_x[:, IX_A] - dS_dcb[:, None] * S,
            "r": dphi_x[:, IX_R],
            "S": dphi_x[:, IX_S] - dS_dcb[:, None] * A,
        }
        h = SUN_RATE_STEP_S
        S_dot = (np.asarray(eph(t_eph + h)[2], dtype=float) - np.asarray(eph(t_eph - h)[2], dtype=float)) / (2 * h)
        d["tau"] = np.einsum("ni,ni->n", d["r"], v) + np.einsum("ni,ni->n", d["S"], S_dot)
        d["d_gamma"] = dphi_x[:, IX_G] + dH_dgamma
        d["d_rho"] = dphi_x[:, IX_DRHO]
        d["d_phi"] = -np.ones_like(psi)
        d["eps_S"] = -(cb / sb) / (np.cos(p["eps_S"]) ** 2 * rS)
        d["eps_H"] = 1.0 / (np.tan(gamma_p) * np.cos(p["eps_H"]) ** 2 * rH)
        d["d_t"] = d["tau"]
        d["horizon_height"] = dphi_x[:, IX_H]
        d["oblateness"] = dphi_x[:, IX_K]
        return psi, d, ok

    def _crossing(self, geom, p, A, P, omega, sign):
        """dt (N,), ∂dt/∂Â (N, 3), ∂dt/∂x dict, ok (N,) for one crossing (implicit solve)."""
        eph = geom.ephemeris
        t = np.asarray(geom.t, dtype=float)
        f_geo = self.flattening(geom)
        psi, ok = self._psi(p, A, t + p["d_t"], eph, sign, False, f_geo)
        dt = np.mod(psi, TWO_PI) / omega
        for _ in range(MAX_ITERATIONS):
            psi, _ = self._psi(p, A, t + dt + p["d_t"], eph, sign, False, f_geo)
            step = wrap_period(psi - omega * dt, TWO_PI) / omega
            dt = dt + step
            if not np.any(np.abs(step) > TOLERANCE_S):  # NaN steps (no crossing) are ignored
                break
        psi, d, ok = self._psi(p, A, t + dt + p["d_t"], eph, sign, True, f_geo)
        y = np.mod(psi, TWO_PI) / omega
        den = omega - d["tau"]  # ω (1 − f_dt)
        d_att = np.einsum("ni,nij->nj", d["A"], P) / den[:, None]
        d_par = {name: d[name] / den for name in (p_.name for p_ in self.parameters())}
        ok &= np.isfinite(y) & (den > 0.0)
        return y, d_att, d_par, ok

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """Eq 4-12 at N Sun sightings: y (N, 2) [s], d_att (N, 2, 3) wrt Â, d_par (N, 2)."""
        specs = self.parameters()
        p = common.merged_params(specs, params)
        if geom.ephemeris is None:
            raise ValueError("horizon model needs the ephemeris callable in the geometry")
        if "spin_rate" not in geom.extra:
            raise InputError(f"horizon sensor '{self.name}' needs the 'spin_rate' telemetry column", column="spin_rate")
        omega = np.asarray(geom.extra["spin_rate"], dtype=float) * np.ones(geom.n)
        with np.errstate(all="ignore"):
            A, P = common.spin_axis_unit(geom)
            y_in, a_in, p_in, ok_in = self._crossing(geom, p, A, P, omega, -1.0)
            y_out, a_out, p_out, ok_out = self._crossing(geom, p, A, P, omega, +1.0)
            valid = ok_in & ok_out & (omega > 0.0)
            if self.observable == "width_midscan":
                period = TWO_PI / omega
                width = np.mod(y_out - y_in, period)
                y = np.column_stack([width, np.mod(y_in + 0.5 * width, period)])
                d_att = np.stack([a_out - a_in, 0.5 * (a_in + a_out)], axis=1)
                d_par = {k: np.column_stack([p_out[k] - p_in[k], 0.5 * (p_in[k] + p_out[k])]) for k in p_in}
            else:
                y = np.column_stack([y_in, y_out])
                d_att = np.stack([a_in, a_out], axis=1)
                d_par = {k: np.column_stack([p_in[k], p_out[k]]) for k in p_in}
        return common.finish(y, d_att, d_par, valid, specs)
