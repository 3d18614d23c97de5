"""Star-tracker headers for the predictor: which star each planned FHST frame identifies.

A headers-only Problem (seed §3.2.2) still needs, for every tracker frame, the catalog
direction ``F_I`` of the identified star: the partials of Eq 4-29/4-31 with respect to
the scale factors ``S_H, S_V`` and the alignment are proportional to where that star
lies in the field. The star models of :attr:`DataPlan.stars
<gcs_core.predictor.plan.DataPlan>`:

* ``"catalog"`` — a real star catalog (:class:`Catalog`, read by :func:`read_catalog`
  from a CSV file ``ra, dec, mag``: a SKYMAP-like run catalog, or the
  ``star_catalog.csv`` a simulated mission directory carries);
* ``"telemetry"`` — the distinct stars ``(ra, dec, mag)`` identified in the mission's own
  tracker telemetry (:func:`telemetry_catalog`): in flight, the stars the trackers
  actually report at the pointing of the next calibration;
* ``"sky"`` — a fixed pseudo-random sky (:class:`SyntheticSky`);
* ``"uniform"`` — one star per frame spread evenly over the field
  (:func:`synthetic_stars`).

For the first three, :func:`catalog_stars` picks the star of each frame as a tracker
does (mirroring :class:`gcs_core.sim.stars.StarTrackerSim`): the candidates are the
catalog stars inside the square field ``|asin F_Sz| ≤ fov`` and
``|atan2(F_Sy, F_Sx)| ≤ fov``, ``F_S = M C_BI F_I``, and no fainter than the tracker's
data-book ``mag_limit`` if it has one (the simulator's trackers have none: their catalog
stops at magnitude 6; a full SKYMAP-like catalog needs the limit, since the summed
brightness of the stars per magnitude keeps growing with ``m``); one of them is
reported with probability ∝ brightness ``10^(−0.4 m)``,
drawn with the golden-ratio sequence so that the prediction is deterministic and the
brightness-weighted mix of stars over a span is the expected one. An inertially fixed
pointing keeps seeing the same few stars, so the scale-factor σ depends on exactly
which stars those are — which only a real catalog gets right.

Catalog file (CSV after ICD §1, read with the project's reader
:mod:`gcs_core.io.csvio`): ``#`` comments and blank lines allowed, one header line
naming at least ``ra, dec, mag`` (extra numeric columns ignored), ``ra`` in [0, 360] deg
and ``dec`` in [−90, 90] deg (J2000), ``mag`` the visual magnitude. Any bad field is an
:class:`~gcs_core.errors.InputError` naming the file, line and column.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from gcs_core.errors import InputError
from gcs_core.io import csvio
from gcs_core.io.types import SensorSpec, Table
from gcs_core.models import common
from gcs_core.predictor.nominal import PlanAttitude, _alignment
from gcs_core.units import DEG

#: the catalog a mission directory may carry (written by :func:`gcs_core.sim.write_mission`)
STAR_CATALOG_FILE = "star_catalog.csv"
CATALOG_COLUMNS = ("ra", "dec", "mag")
#: stars in the synthetic sky (about the count brighter than visual magnitude 6) and its seed
SKY_STARS = 5000
SKY_SEED = 1988
#: telemetry stars closer than this in ra, dec [deg] (and mag) are one catalog entry
SAME_STAR_DEG = 1e-7
#: golden-ratio conjugate: the star-choice sequence ``u_k = frac(0.5 + k φ⁻¹)``
_GOLDEN = 0.6180339887498949
#: the plastic number's powers: R2 low-discrepancy sequence in the unit square
_PLASTIC = 1.324717957244746
_R2 = (1.0 / _PLASTIC, 1.0 / _PLASTIC**2)


def unit_vectors(ra_deg, dec_deg) -> np.ndarray:
    """(n, 3) GCI unit vectors of right ascensions and declinations [deg]."""
    ra, dec = np.asarray(ra_deg, dtype=float) * DEG, np.asarray(dec_deg, dtype=float) * DEG
    return np.column_stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])


class Catalog:
    """A star catalog for tracker headers (what :func:`catalog_stars` needs).

    Attributes
    ----------
    ra_deg, dec_deg, mag : (n,) right ascension, declination [deg, J2000], visual magnitude.
    u_I : (n, 3) GCI unit vectors.
    tree : k-d tree over ``u_I`` (field-of-view queries).
    source : where the stars came from (a file, or ``"<telemetry>"``).
    """

    def __init__(self, ra_deg, dec_deg, mag, *, source: str = ""):
        self.ra_deg = np.asarray(ra_deg, dtype=float).reshape(-1)
        self.dec_deg = np.asarray(dec_deg, dtype=float).reshape(-1)
        self.mag = np.asarray(mag, dtype=float).reshape(-1)
        self.u_I = unit_vectors(self.ra_deg, self.dec_deg)
        self.tree = cKDTree(self.u_I)
        self.source = source

    def __len__(self) -> int:
        return self.mag.size


def read_catalog(path: str | os.PathLike) -> Catalog:
    """Read a star catalog CSV file (module docstring); cached while the file is unchanged.

    Raises :class:`~gcs_core.errors.InputError` naming file, line and column.
    """
    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        raise InputError("star catalog file not found", file=path) from None
    except OSError as err:
        raise InputError(f"cannot read the star catalog file ({err.strerror})", file=path) from None
    return _read_catalog(str(path), st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=4)
def _read_catalog(path_s: str, mtime_ns: int, size: int) -> Catalog:
    path = Path(path_s)
    what = "star catalog"
    try:
        raw = path.read_bytes()
    except IsADirectoryError:
        raise InputError(f"{what} file is a directory", file=path) from None
    except OSError as err:
        raise InputError(f"cannot read the {what} file ({err.strerror})", file=path) from None
    # the reader's own steps (a catalog has no time column, which read_table requires)
    text = csvio._decode(raw, path)
    if "\x00" in text:
        raise InputError(
            "NUL byte in a text file (binary data?)", file=path, line=text[: text.index("\x00")].count("\n") + 1
        )
    names, header_at, eol = csvio._header(text, path, CATALOG_COLUMNS, what)
    rows, linenos = csvio._split_lines(text, header_at, eol)
    data = csvio._parse_bulk(rows, linenos, names, path)
    if data.shape[0] == 0:
        raise InputError(f"no stars: the {what} has a header but no rows", file=path, line=header_at + 1)
    cols = {c: data[:, names.index(c)] for c in CATALOG_COLUMNS}
    checks = (
        ("ra", np.isnan(cols["ra"]), "empty or nan value (a catalog star needs ra, dec and mag)"),
        ("dec", np.isnan(cols["dec"]), "empty or nan value (a catalog star needs ra, dec and mag)"),
        ("mag", np.isnan(cols["mag"]), "empty or nan value (a catalog star needs ra, dec and mag)"),
        ("ra", (cols["ra"] < 0.0) | (cols["ra"] > 360.0), "right ascension outside [0, 360] deg"),
        ("dec", np.abs(cols["dec"]) > 90.0, "declination outside [-90, 90] deg"),
    )
    bad = [(int(np.flatnonzero(m)[0]), c, msg) for c, m, msg in checks if np.any(m)]
    if bad:
        i, c, msg = min(bad, key=lambda b: (b[0], names.index(b[1])))
        k = names.index(c) + 1
        raise InputError(f"{msg} in column {k} '{c}'", file=path, line=linenos[i], column=k)
    return Catalog(cols["ra"], cols["dec"], cols["mag"], source=str(path))


def telemetry_catalog(tables: Iterable[Table]) -> Catalog | None:
    """The distinct stars ``(ra, dec, mag)`` identified in star-tracker telemetry.

    ``tables``: the trackers' telemetry (ICD §5 ``star_tracker`` columns). Entries that agree
    to :data:`SAME_STAR_DEG` are one star. None when no table holds a row.
    """
    rows = [np.column_stack([tab.columns[c] for c in CATALOG_COLUMNS]) for tab in tables if len(tab)]
    if not rows:
        return None
    stars = np.unique(np.round(np.concatenate(rows) / SAME_STAR_DEG) * SAME_STAR_DEG, axis=0)
    return Catalog(stars[:, 0], stars[:, 1], stars[:, 2], source="<telemetry>")


# ----------------------------------------------------------------------------------------
class SyntheticSky:
    """A fixed pseudo-random sky for star-tracker headers (:func:`catalog_stars`).

    ``n`` stars uniform on the sphere with magnitudes ``m ∈ [m_lo, m_hi]`` whose
    cumulative count grows as ``10^(0.48 m)`` (the bright-star counts), drawn once from
    a fixed seed so that every prediction sees the same sky.
    """

    def __init__(self, n: int = SKY_STARS, m_lo: float = 1.0, m_hi: float = 6.0, seed: int = SKY_SEED):
        rng = np.random.default_rng(seed)
        z = rng.uniform(-1.0, 1.0, n)
        lon = rng.uniform(0.0, 2.0 * np.pi, n)
        c = np.sqrt(1.0 - z * z)
        self.u_I = np.column_stack([c * np.cos(lon), c * np.sin(lon), z])
        k = 0.48 * np.log(10.0)
        x = rng.uniform(0.0, 1.0, n)
        self.mag = np.log(np.exp(k * m_lo) + x * (np.exp(k * m_hi) - np.exp(k * m_lo))) / k
        self.tree = cKDTree(self.u_I)


@functools.lru_cache(maxsize=1)
def default_sky() -> SyntheticSky:
    """The shared synthetic sky (built once)."""
    return SyntheticSky()


def catalog_stars(sensor: SensorSpec, t: np.ndarray, nominal: PlanAttitude, catalog) -> tuple[np.ndarray, np.ndarray]:
    """Stars of a catalog seen by a tracker along the nominal attitude: ``(ok, F_I)``.

    ``catalog``: any object with ``u_I`` (n, 3), ``mag`` (n,) and a k-d ``tree`` over
    ``u_I`` (:class:`Catalog`, :class:`SyntheticSky`, :class:`gcs_core.sim.stars.StarCatalog`).
    At each frame the stars inside the square field ``|h|, |v| ≤ fov`` (Eq 4-29 angles
    of ``F_S = M C_BI F_I``), no fainter than the data-book ``mag_limit`` if the sensor
    has one, are the candidates and one is reported with probability
    proportional to its brightness ``10^(−0.4 m)``, drawn with the golden-ratio sequence
    ``u_k = frac(0.5 + k φ⁻¹)`` (deterministic, evenly spread over the weights).
    Returns (N,) frames with a star and (N, 3) its GCI direction (NaN where none).
    """
    fov = common.fov_rad(sensor) or 4.0 * DEG
    mag_limit = common.book_scalar(sensor, "mag_limit", None)
    M_C = _alignment(sensor)[None] @ nominal.dcm(t)
    bore = M_C[:, 0, :]
    radius = 2.0 * np.sin(0.5 * fov * np.sqrt(2.0) * 1.01)  # chord to the field's corner
    cand = catalog.tree.query_ball_point(bore, radius)
    u = np.mod(0.5 + np.arange(1, t.size + 1) * _GOLDEN, 1.0)
    F = np.full((t.size, 3), np.nan)
    ok = np.zeros(t.size, dtype=bool)
    for k, idx in enumerate(cand):
        if not idx:
            continue
        idx = np.asarray(idx)
        FS = catalog.u_I[idx] @ M_C[k].T
        inside = (
            (FS[:, 0] > 0)
            & (np.abs(np.arcsin(np.clip(FS[:, 2], -1, 1))) <= fov)
            & (np.abs(np.arctan2(FS[:, 1], FS[:, 0])) <= fov)
        )
        if mag_limit is not None:
            inside &= catalog.mag[idx] <= mag_limit
        if not np.any(inside):
            continue
        sel = idx[inside]
        w = np.cumsum(10.0 ** (-0.4 * catalog.mag[sel]))
        j = sel[min(int(np.searchsorted(w, u[k] * w[-1])), sel.size - 1)]
        F[k] = catalog.u_I[j]
        ok[k] = True
    return ok, F


def synthetic_stars(sensor: SensorSpec, t: np.ndarray, nominal: PlanAttitude) -> np.ndarray:
    """(N, 3) GCI unit vectors of one star per frame, spread evenly over the field of view.

    "Headers only" (seed §3.2.2): no catalog. The k-th frame's star sits at
    ``(h, v) = fov · (2 u_k − 1)`` in the tracker's square field, ``u_k`` the R2
    low-discrepancy sequence, so that its partials (Eq 4-29, 4-31) sample the field as
    real stars do; then ``F_I = (M C)ᵀ F_S``.
    """
    fov = common.fov_rad(sensor) or 4.0 * DEG
    k = np.arange(1, t.size + 1, dtype=float)
    u = np.mod(0.5 + np.outer(k, _R2), 1.0)
    h = fov * (2.0 * u[:, 0] - 1.0)
    v = fov * (2.0 * u[:, 1] - 1.0)
    F_S = np.column_stack([np.cos(h) * np.cos(v), np.cos(h) * np.sin(v), np.sin(h)])
    M_C = _alignment(sensor)[None] @ nominal.dcm(t)
    return np.einsum("nji,nj->ni", M_C, F_S)
