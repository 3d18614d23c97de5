"""Definitive ephemeris: spacecraft state and Sun position between tabulated rows (ICD §4).

Position is interpolated with a cubic Hermite polynomial on each interval, using the
tabulated velocities as end slopes; the velocity returned is the derivative of that same
polynomial, so position and velocity stay consistent. With ``s = (t − t0)/h``:

    r(t)  = h00(s) r0 + h h10(s) v0 + h01(s) r1 + h h11(s) v1
    h00 = 2s³ − 3s² + 1,  h10 = s³ − 2s² + s,  h01 = −2s³ + 3s²,  h11 = s³ − s²
    v(t)  = [h00'(s) r0 + h h10'(s) v0 + h01'(s) r1 + h h11'(s) v1] / h

The error of cubic Hermite interpolation is ``h⁴/384 max|r⁗|``; for a low Earth orbit
(``|r⁗| ≈ n⁴ |r|``, ``n ≈ 1.1e-3 rad/s``) at a 60 s cadence that is ≈ 3e-4 km (0.3 m).
The derivative is one order less accurate (≈ 2e-5 km/s at 60 s), but it stays in the
orbit plane, so the orbit normal (the earth_pointing y axis) is not disturbed.

Past either end, by at most ``margin_s`` (the importer sets it: a spin period plus the
time-tag bound, for a horizon crossing read after the last Sun sighting), the end
interval's polynomial is extended (cubic Hermite extrapolation; the error grows as
``(Δ/h)² · h⁴ |r⁗|``-order terms, about 1 m for Δ = 20 s at a 60 s cadence in LEO).

The geocentric Sun is interpolated linearly (its direction moves 2.5 arcsec/min).
The Earth's heliocentric velocity, needed for annual aberration, is minus the time
derivative of the geocentric Sun: ``v_E = −ds/dt``, taken by central differences at the
rows and interpolated linearly.

References
----------
de Boor, C., *A Practical Guide to Splines*, Springer 1978, ch. IV (cubic Hermite
interpolation and its error bound).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gcs_core.errors import InputError

__all__ = ["Ephemeris", "EPHEMERIS_COLUMNS"]

#: Columns of ephemeris.csv (ICD §4).
EPHEMERIS_COLUMNS = ("t", "rx", "ry", "rz", "vx", "vy", "vz", "sx", "sy", "sz")

# Query times this close outside the table [s] are treated as on its edge (round-off in
# mission-time arithmetic), not as a coverage gap.
_EDGE_SLACK_S = 1e-6


class Ephemeris:
    """Tabulated GCI spacecraft state and geocentric Sun, interpolated per ICD §4.

    Parameters
    ----------
    t : (M,) seconds since the mission epoch, strictly increasing, M ≥ 2.
    r_I_km : (M, 3) spacecraft position in GCI [km].
    v_I_km_s : (M, 3) spacecraft velocity in GCI [km/s].
    sun_I_km : (M, 3) apparent geocentric Sun position in GCI [km].
    source : name used in messages (the ephemeris file path).
    margin_s : how far past either end the table may be extrapolated [s] (default 0).

    Attributes
    ----------
    t, r_I_km, v_I_km_s, sun_I_km : the table (read-only arrays).
    source : str.
    margin_s : float.
    """

    def __init__(self, t, r_I_km, v_I_km_s, sun_I_km, *, source: str | Path = "ephemeris", margin_s: float = 0.0):
        self.source = str(source)
        self.margin_s = max(0.0, float(margin_s))
        t = np.array(t, dtype=float)
        arrays = {"r_I_km": r_I_km, "v_I_km_s": v_I_km_s, "sun_I_km": sun_I_km}
        if t.ndim != 1 or t.size < 2:
            raise InputError("an ephemeris needs at least two rows", file=self.source)
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
            bad = int(np.argmax(~(np.diff(t) > 0.0))) + 1 if t.size > 1 else 0
            raise InputError(
                f"ephemeris times must be finite and strictly increasing (row {bad + 1})", file=self.source, column="t"
            )
        for name, a in list(arrays.items()):
            a = np.array(a, dtype=float)
            if a.shape != (t.size, 3):
                raise InputError(f"{name} has shape {a.shape}, expected ({t.size}, 3)", file=self.source)
            if not np.all(np.isfinite(a)):
                raise InputError(f"{name} holds non-finite values", file=self.source)
            a.setflags(write=False)
            arrays[name] = a
        t.setflags(write=False)
        self.t = t
        self.r_I_km = arrays["r_I_km"]
        self.v_I_km_s = arrays["v_I_km_s"]
        self.sun_I_km = arrays["sun_I_km"]
        # Earth's heliocentric velocity at the rows: v_E = -ds/dt (second-order differences).
        self._v_earth = -np.gradient(self.sun_I_km, self.t, axis=0)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_table(cls, table, *, margin_s: float = 0.0) -> Ephemeris:
        """Build from an ephemeris.csv :class:`gcs_core.io.types.Table` (ICD §4 columns),
        extrapolated by at most ``margin_s`` past either end."""
        for name in EPHEMERIS_COLUMNS:
            if name not in table.columns:
                raise InputError(
                    "missing column of the ephemeris (ICD §4 needs " + ", ".join(EPHEMERIS_COLUMNS) + ")",
                    file=table.path,
                    column=name,
                )
        cols = table.columns
        return cls(
            np.asarray(table.t, dtype=float),
            np.column_stack([cols["rx"], cols["ry"], cols["rz"]]),
            np.column_stack([cols["vx"], cols["vy"], cols["vz"]]),
            np.column_stack([cols["sx"], cols["sy"], cols["sz"]]),
            source=table.path,
            margin_s=margin_s,
        )

    # ------------------------------------------------------------------ coverage
    @property
    def t_start(self) -> float:
        """First tabulated time [s]."""
        return float(self.t[0])

    @property
    def t_end(self) -> float:
        """Last tabulated time [s]."""
        return float(self.t[-1])

    def covers(self, t) -> np.ndarray:
        """Boolean mask of the times inside ``[t_start − margin_s, t_end + margin_s]``."""
        t = np.asarray(t, dtype=float)
        slack = _EDGE_SLACK_S + self.margin_s
        return (t >= self.t_start - slack) & (t <= self.t_end + slack)

    def check_covers(self, t, *, what: str = "the requested times") -> None:
        """Raise :class:`InputError` unless every time of ``t`` lies in the table's span.

        The message names the ephemeris file, ``what`` needed it (e.g. "telemetry of
        TAM1") and the uncovered span.
        """
        t = np.asarray(t, dtype=float)
        if t.size == 0:
            return
        if np.any(~np.isfinite(t)):
            raise InputError(f"{what}: non-finite time requested from the ephemeris", file=self.source)
        lo, hi = float(np.min(t)), float(np.max(t))
        slack = _EDGE_SLACK_S + self.margin_s
        if lo < self.t_start - slack or hi > self.t_end + slack:
            gaps = []
            if lo < self.t_start - slack:
                gaps.append(f"{lo:.3f} s to {self.t_start:.3f} s")
            if hi > self.t_end + slack:
                gaps.append(f"{self.t_end:.3f} s to {hi:.3f} s")
            ext = f" (extrapolated by at most {self.margin_s:g} s)" if self.margin_s else ""
            raise InputError(
                f"{what} need ephemeris over {lo:.3f}..{hi:.3f} s but it covers "
                f"{self.t_start:.3f}..{self.t_end:.3f} s{ext}; uncovered: " + " and ".join(gaps),
                file=self.source,
            )

    # ------------------------------------------------------------------ interpolation
    def _locate(self, t):
        """Interval index k (t_k ≤ t < t_k+1, clipped) and normalized time s in [0, 1]."""
        k = np.searchsorted(self.t, t, side="right") - 1
        k = np.clip(k, 0, self.t.size - 2)
        h = self.t[k + 1] - self.t[k]
        s = (t - self.t[k]) / h
        return k, s, h

    def state(self, t, *, what: str = "the requested times") -> tuple[np.ndarray, np.ndarray]:
        """Spacecraft position [km] and velocity [km/s] in GCI at times ``t``.

        Cubic Hermite interpolation (module docstring); ``t`` of shape (N,) gives two
        (N, 3) arrays (a scalar ``t`` gives (3,) arrays). Raises :class:`InputError` if
        any time lies outside the table.
        """
        t_arr = np.asarray(t, dtype=float)
        scalar = t_arr.ndim == 0
        t_arr = np.atleast_1d(t_arr)
        self.check_covers(t_arr, what=what)
        k, s, h = self._locate(t_arr)
        s2, s3 = s * s, s * s * s
        # Hermite basis (h00 = 1 − h01 and d00 = −d01 enter through r1 − r0 below)
        h10, h01, h11 = s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
        d10, d01, d11 = 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s
        r0, r1 = self.r_I_km[k], self.r_I_km[k + 1]
        v0, v1 = self.v_I_km_s[k], self.v_I_km_s[k + 1]
        hc = h[:, None]
        # r = h00 r0 + h h10 v0 + h01 r1 + h h11 v1, written about r0 to limit round-off
        r = r0 + h01[:, None] * (r1 - r0) + hc * (h10[:, None] * v0 + h11[:, None] * v1)
        # v = dr/dt = [d00 r0 + h d10 v0 + d01 r1 + h d11 v1] / h   (d00 = -d01)
        v = d01[:, None] * (r1 - r0) / hc + d10[:, None] * v0 + d11[:, None] * v1
        if scalar:
            return r[0], v[0]
        return r, v

    def position(self, t, *, what: str = "the requested times") -> np.ndarray:
        """Spacecraft position [km] in GCI at ``t`` (the position half of :meth:`state`)."""
        return self.state(t, what=what)[0]

    def _linear(self, table, t, what):
        t_arr = np.asarray(t, dtype=float)
        scalar = t_arr.ndim == 0
        t_arr = np.atleast_1d(t_arr)
        self.check_covers(t_arr, what=what)
        k, s, _ = self._locate(t_arr)
        out = table[k] + s[:, None] * (table[k + 1] - table[k])
        return out[0] if scalar else out

    def sun_geocentric(self, t, *, what: str = "the requested times") -> np.ndarray:
        """Geocentric Sun position [km] in GCI at ``t``, linear between rows. (N, 3)."""
        return self._linear(self.sun_I_km, t, what)

    def sun_unit(self, t, *, what: str = "the requested times") -> np.ndarray:
        """Unit vector from the spacecraft to the Sun in GCI: ``(s − r)/|s − r|``. (N, 3).

        This includes solar parallax (up to ~10 arcsec in LEO) but no aberration; see
        :mod:`gcs_core.ephem.corrections` for the spacecraft-velocity aberration.
        """
        r = self.position(t, what=what)
        d = self.sun_geocentric(t, what=what) - r
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def earth_velocity_km_s(self, t, *, what: str = "the requested times") -> np.ndarray:
        """Earth's heliocentric velocity [km/s] in GCI, ``−ds/dt``, for annual aberration. (N, 3)."""
        return self._linear(self._v_earth, t, what)

    def __len__(self) -> int:
        return int(self.t.size)

    def __repr__(self) -> str:
        return f"Ephemeris({self.source!r}, {self.t.size} rows, {self.t_start:.3f}..{self.t_end:.3f} s)"
