"""The Sensor Calibration Data Set (SCDS): an append-only history of calibrations.

The seed's DRIVER updates "the Sensor Calibration Data Set which stores the updated
sensor calibration parameters" (seed §3.2.2). GCS keeps every calibration ever
accepted as a numbered, never-modified version, so that any later analysis can say
which calibration it used and what changed.

HDF5 layout (see docs/formats.md)::

    /                         gcs_format="SCDS", gcs_format_version=1
    /versions/NNNNN           version, created_utc, gcs_version, note, config_hash,
                              data_t0, data_t1, models (JSON), provenance (JSON)
    /versions/NNNNN/param_names   (p,) UTF-8 names, e.g. "TAM1.bias_x"
    /versions/NNNNN/value         (p,) estimates, internal units
    /versions/NNNNN/sigma         (p,) 1-sigma
    /versions/NNNNN/unit          (p,) unit of each
    /versions/NNNNN/element_names (n,) names of the covariance rows/columns
    /versions/NNNNN/covariance    (n, n)  [absent when none was given]

Appending copies the verified file and adds one group, then replaces the file
atomically (:func:`gcs_core.io.h5append.append_group`): a kill at any moment leaves
the previous file intact, and a file that fails its checksums is never written to.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from gcs_core.errors import DataFileError
from gcs_core.io import h5append, h5store

FORMAT = "SCDS"
VERSION = 1
COLLECTION = "versions"
#: provenance keys copied into attributes of their own (the rest stays in the JSON).
PROVENANCE_ATTRS = ("note", "config_hash", "data_t0", "data_t1")


@dataclass(frozen=True)
class VersionSummary:
    """One line of :func:`list_versions`."""

    version: int
    created_utc: str
    gcs_version: str
    note: str
    config_hash: str
    data_t0: float
    data_t1: float
    n_params: int


@dataclass(frozen=True)
class ScdsVersion:
    """One calibration version as read back.

    Attributes
    ----------
    version : its number (1, 2, ...).
    params : element name -> (value, sigma, unit), in stored order.
    element_names : names of the covariance rows and columns.
    covariance : (n, n) covariance of ``element_names``, or None.
    provenance : data span, models, config hash, created UTC, GCS version, note, ...
    """

    version: int
    params: Mapping[str, tuple[float, float, str]]
    element_names: tuple[str, ...]
    covariance: np.ndarray | None
    provenance: Mapping[str, Any] = field(default_factory=dict)

    def value(self, name: str) -> float:
        return self.params[name][0]

    def sigma(self, name: str) -> float:
        return self.params[name][1]


def _check_inputs(sensor_params, covariance, element_names):
    names, values, sigmas, units = [], [], [], []
    for name, entry in sensor_params.items():
        if not isinstance(name, str) or not name:
            raise ValueError(f"parameter names must be non-empty strings, not {name!r}")
        try:
            value, sigma, unit = entry
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected (value, sigma, unit), got {entry!r}") from None
        value, sigma = float(value), float(sigma)
        if not math.isfinite(value) or not (sigma >= 0):
            raise ValueError(f"{name}: value must be finite and sigma >= 0 (got {value}, {sigma})")
        names.append(name)
        values.append(value)
        sigmas.append(sigma)
        units.append(str(unit))
    elements = [str(e) for e in (element_names or ())]
    if len(set(elements)) != len(elements):
        raise ValueError("element_names holds a name twice")
    cov = None
    if covariance is not None:
        cov = np.asarray(covariance, dtype=np.float64)
        if cov.shape != (len(elements), len(elements)):
            raise ValueError(f"covariance has shape {cov.shape}, element_names has {len(elements)} names")
        if not np.all(np.isfinite(cov)):
            raise ValueError("covariance holds non-finite values")
    elif elements:
        raise ValueError("element_names given without a covariance")
    return names, np.array(values), np.array(sigmas), units, elements, cov


def append_version(
    path: str | os.PathLike,
    *,
    sensor_params: Mapping[str, tuple[float, float, str]],
    covariance: np.ndarray | None,
    element_names: Sequence[str],
    provenance: Mapping[str, Any],
) -> int:
    """Append a calibration version to the SCDS (created if absent); return its number.

    Parameters
    ----------
    path : the SCDS file.
    sensor_params : element name (``"TAM1.bias_x"``) -> (value, sigma, unit), internal
        units.
    covariance : (n, n) covariance of ``element_names`` (may hold more elements than
        ``sensor_params``, e.g. attitude), or None.
    element_names : n names of the covariance rows/columns.
    provenance : JSON-serializable facts: ``data_t0``, ``data_t1`` (data span, s since
        epoch), ``models``, ``config_hash``, ``note``, ... ``created_utc`` and
        ``gcs_version`` are filled in when absent.

    Raises
    ------
    DataFileError if the existing file is locked, unreadable or fails a checksum (it is
    then left untouched); ValueError for malformed arguments.
    """
    names, values, sigmas, units, elements, cov = _check_inputs(sensor_params, covariance, element_names)
    prov = dict(provenance or {})
    prov.setdefault("created_utc", h5store.utc_now())
    prov.setdefault("gcs_version", h5store.gcs_version())
    try:
        prov_json = json.dumps(prov, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as err:
        raise ValueError(f"provenance must be JSON-serializable with finite numbers ({err})") from None

    try:
        span = (float(prov.get("data_t0", math.nan)), float(prov.get("data_t1", math.nan)))
    except (TypeError, ValueError):
        raise ValueError("provenance data_t0/data_t1 must be numbers (s since epoch)") from None
    attrs = {
        "created_utc": str(prov["created_utc"]),
        "gcs_version": str(prov["gcs_version"]),
        "note": str(prov.get("note", "")),
        "config_hash": str(prov.get("config_hash", "")),
        "data_t0": span[0],
        "data_t1": span[1],
        "models": json.dumps(prov.get("models", []), default=str),
        "provenance": prov_json,
        "n_params": np.int64(len(names)),
        "has_covariance": bool(cov is not None),
    }

    def build(g: h5py.Group, number: int) -> None:
        g.attrs.update({"version": np.int64(number), **attrs})
        h5store.write_array(g, "param_names", np.array(names, dtype=object))
        h5store.write_array(g, "value", values)
        h5store.write_array(g, "sigma", sigmas)
        h5store.write_array(g, "unit", np.array(units, dtype=object))
        h5store.write_array(g, "element_names", np.array(elements, dtype=object))
        if cov is not None:
            h5store.write_array(g, "covariance", cov)

    return h5append.append_group(path, FORMAT, VERSION, COLLECTION, build, max_version=VERSION)


def _summary(g: h5py.Group) -> VersionSummary:
    a = g.attrs
    return VersionSummary(
        version=int(a["version"]),
        created_utc=h5store.attr_str(g, "created_utc", ""),
        gcs_version=h5store.attr_str(g, "gcs_version", ""),
        note=h5store.attr_str(g, "note", ""),
        config_hash=h5store.attr_str(g, "config_hash", ""),
        data_t0=float(a["data_t0"]),
        data_t1=float(a["data_t1"]),
        n_params=int(a["n_params"]),
    )


def list_versions(path: str | os.PathLike) -> list[VersionSummary]:
    """Every version of the SCDS, oldest first."""
    with h5store.open_read(path, FORMAT, max_version=VERSION) as f:
        return [_summary(f[COLLECTION][n]) for n in h5store.numbered_names(f, COLLECTION)]


def read_version(path: str | os.PathLike, n: int | None = None) -> ScdsVersion:
    """Version ``n`` of the SCDS (the latest when ``n`` is None)."""
    path = Path(path)
    with h5store.open_read(path, FORMAT, max_version=VERSION) as f:
        return _version(h5store.pick_numbered(f, COLLECTION, n, "calibration version", path), path)


def read_versions(path: str | os.PathLike) -> list[ScdsVersion]:
    """Every version of the SCDS, oldest first, in one opening (one checksum pass over the
    file, where reading them one by one would check the whole file once per version)."""
    path = Path(path)
    with h5store.open_read(path, FORMAT, max_version=VERSION) as f:
        return [_version(f[COLLECTION][n], path) for n in h5store.numbered_names(f, COLLECTION)]


def _version(g: h5py.Group, path: Path) -> ScdsVersion:
    """One version group as read back (:class:`ScdsVersion`)."""
    name = g.name.rsplit("/", 1)[-1]
    names = h5store.read_strings(g["param_names"])
    units = h5store.read_strings(g["unit"])
    values, sigmas = g["value"][()], g["sigma"][()]
    if not (len(names) == len(units) == values.size == sigmas.size):
        raise DataFileError(f"version {int(name)} has parameter arrays of unequal length", file=path)
    params = {nm: (float(v), float(s), u) for nm, v, s, u in zip(names, values, sigmas, units)}
    elements = tuple(h5store.read_strings(g["element_names"]))
    cov = g["covariance"][()] if "covariance" in g else None
    prov = json.loads(h5store.attr_str(g, "provenance", "{}"))
    return ScdsVersion(
        version=int(g.attrs["version"]), params=params, element_names=elements, covariance=cov, provenance=prov
    )


def diff_versions(path: str | os.PathLike, a: int, b: int) -> list[tuple[str, float, float, float, float]]:
    """What changed from version ``a`` to version ``b``.

    Returns one ``(element, value_a, value_b, delta, delta_in_sigma)`` per parameter
    of either version (a's order, then b's new ones), ``delta = value_b - value_a`` and
    ``delta_in_sigma = delta / sqrt(sigma_a^2 + sigma_b^2)`` (NaN where a parameter is
    missing from one version or both sigmas are zero and delta is zero; ±inf where only
    the sigmas are zero).
    """
    va, vb = read_version(path, a), read_version(path, b)
    out = []
    for name in list(va.params) + [k for k in vb.params if k not in va.params]:
        xa, sa, _ = va.params.get(name, (math.nan, math.nan, ""))
        xb, sb, _ = vb.params.get(name, (math.nan, math.nan, ""))
        delta = xb - xa
        scale = math.hypot(sa, sb)
        if math.isnan(delta) or math.isnan(scale):
            z = math.nan
        elif scale > 0:
            z = delta / scale
        else:
            z = math.nan if delta == 0 else math.copysign(math.inf, delta)
        out.append((name, xa, xb, delta, z))
    return out
