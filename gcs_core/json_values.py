"""One rule for writing numpy values into JSON and HDF5 attributes.

The reports (ICD §7) and the trade-study records hold numbers that come out of numpy:
scalars (``np.float64``, ``np.int64``, ``np.bool_``), arrays, and paths. ``json.dumps``
knows none of them; :func:`json_default` is its ``default=`` hook for all of them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def json_default(o):
    """A numpy scalar as its Python value, an array as nested lists, a path as text."""
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serializable: {type(o).__name__}")
