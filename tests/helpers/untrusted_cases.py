"""Hostile and careless inputs of issue 23, shared by the tests and benchmarks/fuzz_readers.py.

* :func:`scds_with_versions` — a small valid SCDS;
* :func:`recertify` — rewrite the GCS header of a file changed behind GCS's back, so its
  whole-file SHA-256 is valid again (what a crafted file would carry);
* :func:`craft_scds` — one of the crafted SCDS variants (links, a dataset for a group, a
  30-digit version, a corrupt fletcher32 chunk under a valid SHA, ...);
* :func:`broad_trial` — a small BROAD-like trial (random, seeded; not BROAD's numbers).
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from gcs_core.io import h5store, scds


def params(k: int = 0) -> dict:
    return {"TAM1.bias_x": (3.0 + k, 0.4, "nT"), "TAM1.bias_y": (-1.0, 0.4, "nT")}


def append(path: Path, k: int = 0) -> int:
    return scds.append_version(
        path,
        sensor_params=params(k),
        covariance=np.diag([0.16, 0.16]),
        element_names=["TAM1.bias_x", "TAM1.bias_y"],
        provenance={"data_t0": 0.0, "data_t1": 60.0, "note": f"v{k}"},
    )


def scds_with_versions(path: Path, n: int = 2) -> Path:
    for k in range(n):
        append(path, k)
    return path


def recertify(path: Path, fmt: str = "SCDS") -> None:
    """Give a file changed by h5py a valid GCS header again (length and SHA-256)."""
    h5store._write_header(path, fmt, 1)


#: the crafted SCDS variants :func:`craft_scds` makes
CRAFTS = (
    "soft_link",
    "external_link",
    "versions_dataset",
    "version_dataset",
    "digits_30",
    "digits_6",
    "fletcher_chunk",
    "missing_values",
    "string_values",
    "non_digit_version",
)


def craft_scds(path: Path, craft: str) -> None:
    """Change a valid SCDS at ``path`` into the crafted variant ``craft`` (valid SHA)."""
    with h5py.File(path, "r+", locking=False) as f:
        v = f["versions"]
        first = sorted(v)[0]
        if craft == "soft_link":
            v[first]["note_link"] = h5py.SoftLink("/versions")
        elif craft == "external_link":
            f["passwd"] = h5py.ExternalLink("/etc/passwd", "/")
        elif craft == "versions_dataset":
            del f["versions"]
            f["versions"] = np.arange(3)
        elif craft == "version_dataset":
            f["versions/00099"] = np.arange(3)
        elif craft == "digits_30":
            f.copy(v[first], v, name="1" * 30)
        elif craft == "digits_6":
            g = f.copy(v[first], v, name="100000") or v["100000"]
            g.attrs["version"] = np.int64(100000)
        elif craft == "missing_values":
            del v[first]["value"]
        elif craft == "string_values":
            del v[first]["sigma"]
            v[first]["sigma"] = np.array([b"x", b"y"])
        elif craft == "non_digit_version":
            f.copy(v[first], v, name="²³")
        elif craft == "fletcher_chunk":
            ds = v[first]["value"]
            offset = ds.id.get_chunk_info(0).byte_offset
        else:
            raise ValueError(craft)
    if craft == "fletcher_chunk":
        with open(path, "r+b") as fh:
            fh.seek(offset)
            b = fh.read(1)
            fh.seek(offset)
            fh.write(bytes([b[0] ^ 0xFF]))
    recertify(path)


def broad_trial(path: Path, n: int = 400, rate: float = 50.0, seed: int = 3) -> Path:
    """A small BROAD-like trial: the datasets and attribute the converter reads."""
    rng = np.random.default_rng(seed)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) + rng.normal(scale=1e-4, size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    with h5py.File(path, "w") as f:
        f["imu_gyr"] = 0.003 + rng.normal(scale=2e-3, size=(n, 3))
        f["imu_acc"] = rng.normal(size=(n, 3))
        f["imu_mag"] = np.array([0.5, 17.0, -45.0]) + rng.normal(scale=0.5, size=(n, 3))
        f["opt_quat"] = q
        f["opt_pos"] = rng.normal(size=(n, 3))
        f["movement"] = np.arange(n) > n // 2
        f.attrs["sampling_rate"] = rate
    return path
