"""The noise figures of a BROAD trial, estimated from its own telemetry, for
:mod:`gcs_core.convert.broad` (its docstring says what and why).

Each sensor's per-sample spread (second differences, :func:`gcs_core.noise.measured.white_noise`)
over the samples used, and the white-noise lines of the Allan deviation at rest (consecutive
samples of the unit are correlated: the per-sample spread understates the noise that slow
parameters see): the gyro's angle and rate random walks, the magnetometer's σ per sample
used (its held repeats left out: irregularly spaced), the optical reference's per sample.
A channel constant at rest shows no noise there: its spread, else a floor, stands in, with
a warning (:func:`_floor`). The gyro's data-book bias is its mean at rest.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gcs_core.errors import InputError
from gcs_core.noise import measured as noise_mod

if TYPE_CHECKING:
    from gcs_core.convert.broad import Flags, Trial

#: the fewest samples at rest (tracked ones, for the optical reference) the noise is measured on
MIN_REST = 64


@dataclass(frozen=True)
class Noise:
    """A trial's noise figures (module docstring).

    s_gyr [rad/s], s_mag [nT], s_opt [rad] : (3,) per-sample spreads of the samples used;
    arw [rad/s^0.5], rrw [rad/s^1.5] : the gyro's random walks (RMS over the axes);
    m_line [nT] : (3,) the magnetometer's white-noise line per sample used, one every
    m_dt [s] on average; o_line [rad] : (3,) the optical reference's per sample;
    bias0 [rad/s] : (3,) the gyro's mean at rest, over n_rest samples.
    """

    s_gyr: np.ndarray
    s_mag: np.ndarray
    s_opt: np.ndarray
    arw: float
    rrw: float
    m_line: np.ndarray
    m_dt: float
    o_line: np.ndarray
    bias0: np.ndarray
    n_rest: int

    def notes(self) -> list[str]:
        """What was estimated, for the report."""
        return [
            f"noise estimated from the telemetry: per-sample spread (second differences) "
            f"gyro {np.array2string(self.s_gyr, precision=4)} rad/s, magnetometer "
            f"{np.array2string(self.s_mag, precision=1)} nT, optical "
            f"{np.array2string(self.s_opt, precision=7)} rad; white-noise lines at rest "
            f"(Allan deviation): gyro ARW {self.arw:.4g} rad/s^0.5, magnetometer "
            f"{np.array2string(self.m_line, precision=1)} nT per sample used "
            f"(every {1e3 * self.m_dt:.3f} ms on average), optical "
            f"{np.array2string(self.o_line, precision=7)} rad per sample",
            f"gyro data-book bias = mean over the rest ({self.n_rest} samples)",
        ]


def rest_samples(moving: np.ndarray) -> np.ndarray:
    """(N,) the samples the noise and the gyro's rest bias are measured on: the middle
    half of the longest run outside the motion phase (the unit is often picked up, or
    still swinging, a few seconds on either side of the phase flagged as motion)."""
    still = ~np.asarray(moving, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
    runs = edges.reshape(-1, 2)
    out = np.zeros(still.size, dtype=bool)
    if runs.size:
        lo, hi = runs[int(np.argmax(runs[:, 1] - runs[:, 0]))]
        q = (hi - lo) // 4
        out[lo + q : hi - q] = True
    return out


def _floor(line: np.ndarray, spread: np.ndarray, tiny: float, what: str, unit: str, warnings: list[str]) -> np.ndarray:
    """``line`` where it is a positive number; elsewhere the per-sample spread, else ``tiny``."""
    bad = ~(np.isfinite(line) & (line > 0))
    if not bad.any():
        return line
    out = np.where(bad, np.where(np.isfinite(spread) & (spread > 0), spread, tiny), line)
    warnings.append(
        f"{what}: no noise measurable at rest on {int(bad.sum())} axis(es); "
        f"written {np.array2string(out, precision=4)} {unit} from the per-sample "
        "spread (or a floor): check it"
    )
    return out


def rms(v) -> float:
    v = np.asarray(v, dtype=float)
    return float(np.sqrt(np.mean(v * v)))


def _white_lines(t: np.ndarray, y: np.ndarray, dt: float, *, quaternion: bool = False) -> np.ndarray:
    """(3,) the white-noise line of each axis's Allan deviation, per sample ``dt`` [s]."""
    return np.array([noise_mod.white_level(c, dt)[0] for c in noise_mod.allan_deviation(t, y, quaternion=quaternion)])


def estimate(trial: Trial, flags: Flags, source: Path, warnings: list[str]) -> Noise:
    """The trial's noise figures (module docstring); a floor stood in is a warning added
    to ``warnings``. Too few samples at rest is an InputError naming ``source``."""
    t, gyr, mag_nT, q_gcs, rest0 = trial.t, trial.gyr, trial.mag_nT, trial.q_gcs, trial.rest
    dt = 1.0 / trial.rate
    s_gyr = noise_mod.white_noise(t[~flags.g_held], gyr[~flags.g_held])
    s_mag = noise_mod.white_noise(t[~flags.m_held], mag_nT[~flags.m_held])  # the samples used
    s_opt = noise_mod.white_noise(t[trial.tracked], q_gcs[trial.tracked], quaternion=True)
    if rest0.sum() < MIN_REST:
        raise InputError(
            f"only {int(rest0.sum())} samples at rest: too few to measure the noise", file=source, key="movement"
        )
    g_terms = [noise_mod.gyro_terms(c) for c in noise_mod.allan_deviation(t[rest0], gyr[rest0])]
    arw = rms([g.arw for g in g_terms])
    rrw = rms([g.rrw for g in g_terms])
    m_use = rest0 & ~flags.m_held  # irregularly spaced where held repeats are left out: per sample used
    m_dt = noise_mod.mean_interval(t[m_use])
    m_line = _white_lines(t[m_use], mag_nT[m_use], m_dt)
    opt_rest = rest0 & trial.tracked
    if opt_rest.sum() < MIN_REST:
        raise InputError(
            f"only {int(opt_rest.sum())} tracked optical samples at rest: too few to measure the noise",
            file=source,
            key="opt_quat",
        )
    o_line = _white_lines(t[opt_rest], q_gcs[opt_rest], dt, quaternion=True)
    # a channel constant at rest (or quantized coarser than its noise) shows no noise there:
    # its per-sample spread over the whole span, else a floor, stands in (and is reported)
    m_line = _floor(m_line, s_mag, 1e-3, "magnetometer", "nT", warnings)
    o_line = _floor(o_line, s_opt, 1e-9, "optical reference", "rad", warnings)
    if not arw > 0:
        arw = float(_floor(np.array([0.0]), np.array([rms(s_gyr)]), 1e-9, "gyro", "rad/s", warnings)[0]) * np.sqrt(dt)
    bias0 = gyr[rest0].mean(axis=0)
    return Noise(s_gyr, s_mag, s_opt, arw, rrw, m_line, m_dt, o_line, bias0, int(rest0.sum()))
