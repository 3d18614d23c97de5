"""The Attitude Status File (ASF): ground attitudes, append-only (seed §3.2.2).

The seed's DRIVER writes "the Attitude Status File which stores the attitude
determination results", and VERIF reads the attitudes to be verified from it. GCS keeps
each attitude history (a batch solution, a filter run, an imported onboard history) as
a numbered solution that is never modified once written.

HDF5 layout (see docs/formats.md)::

    /                          gcs_format="ASF", gcs_format_version=1
    /solutions/NNNNN           solution, source, created_utc, gcs_version, note,
                               n, t0, t1, scds_version, provenance (JSON)
    /solutions/NNNNN/t         (N,) s since the mission epoch
    /solutions/NNNNN/q         (N, 4) q1, q2, q3, q4 (scalar last), GCI to body (ICD §2)
    /solutions/NNNNN/sigma_rad (N, 3) 1-sigma attitude error about body x, y, z [rad]

Appending works as for the SCDS (:func:`gcs_core.io.h5append.append_group`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from gcs_core.errors import DataFileError
from gcs_core.io import h5append, h5store

FORMAT = "ASF"
VERSION = 1
COLLECTION = "solutions"
QUATERNION_NORM_TOL = 1e-6


@dataclass(frozen=True)
class AsfSummary:
    """One line of :func:`list_solutions`."""

    solution: int
    source: str
    created_utc: str
    note: str
    n: int
    t0: float
    t1: float


@dataclass(frozen=True)
class AsfSolution:
    """One attitude history.

    Attributes
    ----------
    solution : its number (1, 2, ...).
    source : what produced it ("batch", "filter", "onboard", ...).
    t : (N,) s since epoch, strictly increasing.
    q : (N, 4) quaternions (q1, q2, q3, q4), scalar last, GCI to body, unit norm.
    sigma_rad : (N, 3) 1-sigma attitude error about the body axes [rad].
    provenance : created UTC, GCS version, SCDS version used, note, ...
    """

    solution: int
    source: str
    t: np.ndarray
    q: np.ndarray
    sigma_rad: np.ndarray
    provenance: Mapping[str, Any] = field(default_factory=dict)


def _check(t, q, sigma) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    q = np.asarray(q, dtype=np.float64)
    sigma = np.asarray(sigma, dtype=np.float64)
    n = t.size
    if q.shape != (n, 4):
        raise ValueError(f"q must have shape ({n}, 4), not {q.shape}")
    if sigma.shape != (n, 3):
        raise ValueError(f"sigma must have shape ({n}, 3), not {sigma.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
        raise ValueError("t and q must be finite")
    if n > 1 and np.any(np.diff(t) <= 0):
        raise ValueError("t must be strictly increasing")
    norm = np.linalg.norm(q, axis=1)
    if n and np.max(np.abs(norm - 1.0)) > QUATERNION_NORM_TOL:
        raise ValueError(f"quaternions must have unit norm (worst {norm[np.argmax(np.abs(norm - 1))]:.9g})")
    if np.any(~(sigma >= 0) & ~np.isnan(sigma)):
        raise ValueError("sigma must be >= 0 (NaN for unknown)")
    return t, q, sigma


def append_solution(
    path: str | os.PathLike, *, t, q, sigma, source: str, provenance: Mapping[str, Any] | None = None
) -> int:
    """Append an attitude history to the ASF (created if absent); return its number.

    Parameters
    ----------
    t : (N,) s since epoch, strictly increasing.
    q : (N, 4) unit quaternions, scalar last, GCI to body (ICD §2, Eq 4-8).
    sigma : (N, 3) 1-sigma attitude errors about body x, y, z [rad] (NaN if unknown).
    source : what produced it ("batch", "filter", "onboard", ...).
    provenance : JSON-serializable facts (``note``, ``scds_version``, config hash...);
        ``created_utc`` and ``gcs_version`` are filled in when absent.
    """
    t, q, sigma = _check(t, q, sigma)
    if not isinstance(source, str) or not source:
        raise ValueError("source must be a non-empty string")
    prov = dict(provenance or {})
    prov.setdefault("created_utc", h5store.utc_now())
    prov.setdefault("gcs_version", h5store.gcs_version())
    try:
        prov_json = json.dumps(prov, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as err:
        raise ValueError(f"provenance must be JSON-serializable ({err})") from None
    scds_version = prov.get("scds_version")
    attrs = {
        "source": source,
        "created_utc": str(prov["created_utc"]),
        "gcs_version": str(prov["gcs_version"]),
        "note": str(prov.get("note", "")),
        "n": np.int64(t.size),
        "t0": float(t[0]) if t.size else np.nan,
        "t1": float(t[-1]) if t.size else np.nan,
        "scds_version": np.int64(scds_version) if isinstance(scds_version, int) else -1,
        "provenance": prov_json,
    }

    def build(g: h5py.Group, number: int) -> None:
        g.attrs.update({"solution": np.int64(number), **attrs})
        h5store.write_array(g, "t", t, attrs={"unit": "s"})
        h5store.write_array(g, "q", q, attrs={"convention": "q1, q2, q3, q4 (scalar last), GCI to body"})
        h5store.write_array(g, "sigma_rad", sigma, attrs={"unit": "rad"})

    return h5append.append_group(path, FORMAT, VERSION, COLLECTION, build, max_version=VERSION)


def list_solutions(path: str | os.PathLike) -> list[AsfSummary]:
    """Every solution of the ASF, oldest first."""
    with h5store.open_read(path, FORMAT, max_version=VERSION) as f:
        out = []
        for name in h5store.numbered_names(f, COLLECTION):
            g = f[COLLECTION][name]
            a = g.attrs
            out.append(
                AsfSummary(
                    solution=int(a["solution"]),
                    source=h5store.attr_str(g, "source", ""),
                    created_utc=h5store.attr_str(g, "created_utc", ""),
                    note=h5store.attr_str(g, "note", ""),
                    n=int(a["n"]),
                    t0=float(a["t0"]),
                    t1=float(a["t1"]),
                )
            )
        return out


def read_solution(path: str | os.PathLike, n: int | None = None) -> AsfSolution:
    """Solution ``n`` of the ASF (the latest when ``n`` is None)."""
    path = Path(path)
    with h5store.open_read(path, FORMAT, max_version=VERSION) as f:
        g = h5store.pick_numbered(f, COLLECTION, n, "attitude solution", path)
        name = g.name.rsplit("/", 1)[-1]
        t, q, sigma = g["t"][()], g["q"][()], g["sigma_rad"][()]
        if q.shape != (t.size, 4) or sigma.shape != (t.size, 3):
            raise DataFileError(f"solution {int(name)} has arrays of inconsistent shapes", file=path)
        return AsfSolution(
            solution=int(g.attrs["solution"]),
            source=h5store.attr_str(g, "source", ""),
            t=t,
            q=q,
            sigma_rad=sigma,
            provenance=json.loads(h5store.attr_str(g, "provenance", "{}")),
        )
