"""The batch's data editing (seed §3.2.1: k-σ editing), shared by the whole-span fit: the
frames beyond ``k`` robust σ of a sensor's residuals (:func:`robust_outliers`), flagged pass
after pass (:func:`edit_frames`), and the note on sensors too bad to edit (the model, not
the data, is wrong: :func:`suspect_note`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from gcs_core.noise.measured import MAD_TO_SIGMA
from gcs_core.problem.build import Problem

if TYPE_CHECKING:  # the options are the batch's; this module is below it
    from gcs_core.estimators.batch.least_squares import BatchOptions


def edit_frames(
    problem: Problem,
    buffers,
    preflag: Mapping[str, np.ndarray],
    opts: BatchOptions,
    previous: Mapping[str, np.ndarray],
    scale: Mapping[str, np.ndarray] | None = None,
):
    """k-σ editing of every sensor's residuals by the robust rule (:func:`robust_outliers`),
    on top of the frames flagged before the fit (``preflag``); ``scale`` gives a sensor's
    (N, m) σ per row where it is not the data book's (the whole-span fit's marginal σ under
    the gyro's read-out noise).

    A sensor that would lose more than ``opts.max_edit_fraction`` of its frames is not
    edited: that many outliers is a model error to report and rank, not outliers. Returns
    (sensor -> edited mask, names of such sensors, whether the masks differ from ``previous``).
    """
    new_edits, suspect = {}, set()
    for sd in problem.sensors:
        valid = buffers.valid[sd.name]
        pre = preflag.get(sd.name, np.zeros(valid.shape, bool))
        k = opts.k_for(sd.name)
        if k is None:
            new_edits[sd.name] = pre
            continue
        sig = sd.sigma if scale is None or sd.name not in scale else scale[sd.name]
        out = robust_outliers(buffers.r[sd.name] / sig, valid & ~pre, k)
        n_valid = max(1, int(np.count_nonzero(valid & ~pre)))
        if np.count_nonzero(out) > opts.max_edit_fraction * n_valid:
            suspect.add(sd.name)
            out[:] = False
        new_edits[sd.name] = pre | out
    changed = any(not np.array_equal(m, previous.get(k, np.zeros_like(m))) for k, m in new_edits.items())
    return new_edits, suspect, changed


def suspect_note(suspect, opts: BatchOptions) -> str:
    """What a fit's message adds for the sensors :func:`edit_frames` left unedited ('' for none)."""
    if not suspect:
        return ""
    return (
        "; not edited (more than "
        f"{100 * opts.max_edit_fraction:g}% of frames beyond their k σ, the model "
        "is suspect): " + ", ".join(sorted(suspect))
    )


def robust_outliers(z: np.ndarray, candidates: np.ndarray, k: float) -> np.ndarray:
    """Frames whose normalized residual ``z`` (N, m) is an outlier, among ``candidates``.

    A frame is flagged when any component lies more than ``k · max(1, s)`` from the
    component's median, ``s`` being the robust scale of the normalized residuals
    (1.4826 × the median absolute deviation, pooled over components; 1.0 at the noise
    floor for Gaussian noise). Scaling the threshold by ``s`` keeps the editing for
    isolated gross errors (a misidentified star, a telemetry hit): a model that misses a
    physical effect widens the whole distribution, ``s`` grows with it, and the signature
    the diagnosis needs is not edited away. Gross outliers cannot mask themselves
    either, since the median and MAD ignore up to half of the frames.

    References
    ----------
    Hampel, Ronchetti, Rousseeuw & Stahel, *Robust Statistics*, Wiley 1986, §2.6
    (the MAD and its 1.4826 consistency factor for the normal law).
    """
    out = np.zeros(candidates.shape, bool)
    if not np.any(candidates):
        return out
    zc = z[candidates]
    with np.errstate(invalid="ignore"):
        dev = np.abs(zc - np.nanmedian(zc, axis=0))
        s = MAD_TO_SIGMA * float(np.nanmedian(dev))
        big = np.any(dev > k * max(1.0, s if np.isfinite(s) else 1.0), axis=1)
    out[np.flatnonzero(candidates)[big]] = True
    return out
