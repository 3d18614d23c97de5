"""Noise from the data: each sensor's white noise and Allan deviation from its own telemetry.

A real data book rarely carries a trustworthy noise figure, and normalized residuals are
only as meaningful as the σ they are divided by. This module measures the noise a sensor
*shows*:

* :func:`white_noise` — the 1-σ white noise per component from robust second differences
  of consecutive samples. For ``y_k = s(t_k) + n_k`` with white ``n`` of variance σ²,
  ``Δ²y_k = y_{k+1} − 2 y_k + y_{k−1}`` has variance ``6 σ²`` plus ``s''Δt²``, which at
  the sample rates of attitude sensors is far below the noise; the spread is taken as
  1.4826 × the median absolute deviation (immune to a few telemetry hits and to the
  fast parts of a manoeuvre). Only triples of samples one interval apart are used.
* :func:`allan_deviation` — the overlapping Allan deviation at octave cluster times
  ``τ = m τ0``, ``m = 1, 2, 4, …`` (IEEE Std 952-1997, Annex C, Eq C.2 with the
  overlapping estimator)::

      θ_k = τ0 Σ_{i<k} y_i,
      σ²(τ) = Σ_{k=0}^{N−2m} (θ_{k+2m} − 2 θ_{k+m} + θ_k)² / (2 τ² (N − 2m))

  For white noise of per-sample σ, ``σ(τ0) = σ`` and ``σ(τ) = σ sqrt(τ0/τ)``.
  *Irregularly spaced samples* (a sensor's held repeats flagged and left out, short
  dropouts) are placed on the grid of their median interval τ0 with empty slots; the
  cluster averages ``ȳ`` are the means of the samples inside each window of τ, and
  ``σ²(τ) = ½ ⟨(ȳ_{k+m} − ȳ_k)²⟩ · τ̄/(τ h̄)`` over the pairs of non-empty windows, with
  ``h̄ = ⟨½(1/n_k + 1/n_{k+m})⟩`` (n the samples in a window) and τ̄ the mean interval
  of the samples used: white noise of per-sample σ then gives ``σ sqrt(τ̄/τ)`` at
  every τ, so the white-noise line (:func:`white_level` with ``dt =``
  :func:`mean_interval`) is the σ *per sample used*. On regular samples ``h̄ = τ0/τ``,
  ``τ̄ = τ0``, and this is Eq C.2 exactly. Only an interval longer than
  :data:`HOLE_FACTOR` τ0 breaks the run.
* :func:`gyro_terms` — the angle random walk N (the −1/2 slope, read at τ = 1 s), the
  rate random walk K (the +1/2 slope, read at τ = 3 s) and the bias instability
  B (the flat minimum / 0.664), IEEE Std 952-1997 Annex C, Table C.2 / Fig C.2. N is
  ``σ(τ) sqrt(τ)`` at the short-τ point whose local slope is nearest −1/2 (the −1/2
  line extended to 1 s); since ``σ²(τ) ≥ K² τ/3`` at every τ when the terms are
  independent, K is the lowest ``σ(τ) sqrt(3/τ)`` over the curve: the term itself
  where the +1/2 slope shows, an upper bound (flagged) where the curve never reaches it.
* :func:`noise_estimated` — whether a mission.toml marks a sensor's noise figure as
  estimated from its own telemetry: the converters write :data:`ESTIMATED_MARK` in the
  comment of the key (``noise``, or a gyro's ``arw``/``rrw``) or in the comment lines
  directly above it; reports then say "against the noise this sensor shows".
* :func:`white_level` — any sensor's white-noise line as a per-sample σ (the σ of the
  white noise with the sensor's low-frequency density), for sensors whose consecutive
  samples are correlated.

Attitude references (quaternions) are differenced as rotations: the increments
``rotvec(C_{k+1} C_kᵀ)`` stand for the first differences; their Allan curve is of the small
angles from the mean attitude (:func:`small_angles`), meaningful over a still span.

Consecutive samples of real units are often correlated (a sensor read faster than it
updates and interpolated, or filtered): the second differences then see only part of
the noise, and the white-noise line of the Allan curve over a still span is the figure
that makes the σ of slowly varying parameters honest.

References
----------
IEEE Std 952-1997, *IEEE Standard Specification Format Guide and Test Procedure for
Single-Axis Interferometric Fiber Optic Gyros*, Annex C (Allan variance).
El-Sheimy, N., Hou, H., Niu, X., "Analysis and modeling of inertial sensors using Allan
variance", IEEE Trans. Instrum. Meas. 57(1), 2008.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_core.errors import InputError
from gcs_core.frames.rotations import dcm_to_rotvec, quat_normalize, quat_to_dcm, rotvec_to_dcm

#: consistency constant of the median absolute deviation for a normal distribution
MAD_TO_SIGMA = 1.4826
#: second differences further than this many σ from their median are left out (hits)
CLIP_SIGMA = 5.0
#: intervals up to this multiple of the median are holes within one run of the Allan
#: deviation (held repeats left out, short dropouts); longer ones break it
HOLE_FACTOR = 8.0
#: the Allan curve stops when fewer than this many independent clusters remain
MIN_CLUSTERS = 4
#: bias instability from the flat minimum: σ_min = sqrt(2 ln 2 / π) B ≈ 0.664 B (IEEE 952 C.2)
BIAS_INSTABILITY_FACTOR = 0.664
#: the τ at which the ARW and RRW lines are read (IEEE 952 Annex C)
ARW_TAU_S = 1.0
RRW_TAU_S = 3.0
#: a term counts as read on its slope when the local slope is within this of the ideal
SLOPE_TOLERANCE = 0.15
#: the one marker, in mission.toml, of a noise figure estimated from the data (written by
#: every converter, read by :func:`noise_estimated`)
ESTIMATED_MARK = "ESTIMATED from the data"
#: the data-book keys that carry a sensor's noise
NOISE_KEYS = ("noise", "arw", "rrw")


@dataclass(frozen=True)
class AllanCurve:
    """An overlapping Allan deviation curve of one component.

    Attributes
    ----------
    tau : (K,) cluster times [s], octaves of the sample interval.
    adev : (K,) Allan deviation [unit of the samples].
    clusters : (K,) number of overlapping cluster differences behind each point.
    """

    tau: np.ndarray
    adev: np.ndarray
    clusters: np.ndarray

    def slope(self) -> np.ndarray:
        """(K,) local log-log slope (centred differences, one-sided at the ends)."""
        if self.tau.size < 2:
            return np.full(self.tau.shape, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.gradient(np.log(self.adev), np.log(self.tau))


@dataclass(frozen=True)
class GyroTerms:
    """Gyro noise terms read off an Allan curve (IEEE Std 952-1997 Annex C).

    Attributes
    ----------
    arw : angle random walk N [rad/s^0.5] (= [rad/s/√Hz]).
    arw_tau : τ [s] where it was read; ``arw_bound``: True if the curve never shows the
        −1/2 slope there (N is then an upper bound).
    rrw : rate random walk K [rad/s^1.5]; ``rrw_tau``, ``rrw_bound`` likewise (+1/2 slope).
    bias_instability : B [rad/s] = min σ(τ) / 0.664; ``bias_tau`` where the minimum lies.
    """

    arw: float
    arw_tau: float
    arw_bound: bool
    rrw: float
    rrw_tau: float
    rrw_bound: bool
    bias_instability: float
    bias_tau: float


def sample_interval(t: np.ndarray) -> float:
    """Median sample interval [s] of sorted times ``t`` (N,)."""
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        raise InputError(f"{t.size} samples: at least 2 are needed to measure noise")
    return float(np.median(np.diff(t)))


def _increments(y: np.ndarray, quaternion: bool) -> np.ndarray:
    """First differences (N−1, m): of the values, or the rotation vectors between
    consecutive attitudes of a quaternion sensor."""
    if quaternion:
        C = quat_to_dcm(quat_normalize(np.asarray(y, dtype=float)))
        return dcm_to_rotvec(C[1:] @ np.swapaxes(C[:-1], -1, -2))
    return np.diff(np.asarray(y, dtype=float), axis=0)


def _clipped_std(x: np.ndarray) -> np.ndarray:
    """Per-column standard deviation about the median after iterated
    :data:`CLIP_SIGMA`-σ clipping (robust to telemetry hits, unbiased by quantization,
    which defeats a median absolute deviation when the noise spans a few steps)."""
    med = np.median(x, axis=0)
    s = MAD_TO_SIGMA * np.median(np.abs(x - med), axis=0)
    s = np.where(s > 0, s, np.std(x, axis=0))
    for _ in range(3):
        out = np.empty(x.shape[1])
        for c in range(x.shape[1]):
            col = x[:, c]
            keep = np.abs(col - med[c]) <= CLIP_SIGMA * max(s[c], 1e-300)
            out[c] = np.sqrt(np.mean((col[keep] - med[c]) ** 2)) if keep.any() else s[c]
        s = out
    return s


def white_noise(t: np.ndarray, y: np.ndarray, *, quaternion: bool = False) -> np.ndarray:
    """1-σ noise per sample and component from second differences (module docstring).

    A sample equal to the one before in every component is a held value (a sensor
    read more often than it updates), not a new measurement, and is skipped. On
    irregularly spaced samples (held repeats flagged and left out by the import) the
    second difference of each triple is that of unequal intervals ``h1, h2`` (exact for
    a straight line), ``(y2 − y1)/h2 − (y1 − y0)/h1``, divided by its σ for unit white
    noise, ``sqrt(1/h1² + (1/h1 + 1/h2)² + 1/h2²)``: the spread of the samples used. The
    intervals are taken in whole median intervals (the ticks of the bus that read the
    sensor; on regular samples this is ``Δ²y/√6``); triples across an interval over
    :data:`HOLE_FACTOR` median intervals are left out.

    Parameters
    ----------
    t : (N,) sample times [s], increasing.
    y : (N, m) samples, or (N, 4) unit quaternions (scalar last) with ``quaternion``.

    Returns
    -------
    (m,) σ in the units of ``y`` (rad per axis for quaternions).
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    fresh = np.ones(y.shape[0], dtype=bool)
    if y.shape[0] > 1:
        fresh[1:] = np.any(np.diff(y, axis=0) != 0.0, axis=1)
    kept = np.flatnonzero(fresh)
    t, y = t[fresh], y[fresh]
    d = _increments(y, quaternion)
    dt = sample_interval(t)
    h = np.rint(np.diff(t) / dt) * dt  # on the grid of the median interval (a bus's ticks)
    # unequal intervals as given, not made here by skipping a repeat
    ok = (h > 0) & (h < HOLE_FACTOR * dt) & ((np.diff(kept) == 1) | np.isclose(h, dt))
    both = ok[1:] & ok[:-1]
    h1, h2 = h[:-1][both], h[1:][both]
    # the second difference of unequally spaced samples, (y2−y1)/h2 − (y1−y0)/h1, and its σ
    # for white noise of σ 1: sqrt(1/h1² + (1/h1 + 1/h2)² + 1/h2²) (√6/h when regular)
    dd = d[1:][both] / h2[:, None] - d[:-1][both] / h1[:, None]
    scale = np.sqrt(1.0 / h1**2 + (1.0 / h1 + 1.0 / h2) ** 2 + 1.0 / h2**2)
    if dd.shape[0] < 10:
        raise InputError(f"only {dd.shape[0]} runs of three consecutive samples: too few to measure the noise")
    return _clipped_std(dd / scale[:, None])


def white_level(curve: AllanCurve, dt: float) -> tuple[float, float, bool]:
    """The white-noise line of an Allan curve as a per-sample σ: ``σ(τ) sqrt(τ/τ0)`` read
    at the short-τ point whose local slope is nearest −1/2 (the first half of the curve).

    This is the σ of the white noise with the same low-frequency density as the sensor's:
    the honest per-sample σ for estimating slow parameters when consecutive samples are
    correlated (a sensor filtered or read faster than it updates), where the per-sample
    spread of :func:`white_noise` is smaller. Returns ``(σ, τ, bound)``, ``bound`` True
    when no point lies within :data:`SLOPE_TOLERANCE` of −1/2.
    """
    slope = curve.slope()
    half = max(1, (curve.tau.size + 1) // 2)
    i = int(np.argmin(np.abs(slope[:half] + 0.5)))
    return (
        float(curve.adev[i] * np.sqrt(curve.tau[i] / dt)),
        float(curve.tau[i]),
        bool(abs(slope[i] + 0.5) > SLOPE_TOLERANCE),
    )


def small_angles(q: np.ndarray) -> np.ndarray:
    """(N, 3) [rad] the rotation of each attitude (N, 4) from their mean attitude, about
    the mean's axes: ``e_k = rotvec(C_k C̄ᵀ)``, ``C̄`` the first attitude corrected by the
    mean of the angles from it. Small, and meaningful, over a still span only."""
    C = quat_to_dcm(quat_normalize(np.asarray(q, dtype=float)))
    e0 = dcm_to_rotvec(C @ C[0].T)
    Cbar = rotvec_to_dcm(e0.mean(axis=0)) @ C[0]
    return dcm_to_rotvec(C @ Cbar.T)


def _runs(t: np.ndarray, dt: float) -> tuple[int, int]:
    """``(lo, hi)`` of the longest run of ``t`` without an interval over HOLE_FACTOR·dt."""
    breaks = np.flatnonzero(np.diff(t) >= HOLE_FACTOR * dt)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks + 1, [t.size]])
    k = int(np.argmax(ends - starts))
    return int(starts[k]), int(ends[k])


def mean_interval(t: np.ndarray) -> float:
    """Mean interval [s] between the samples used, over the run :func:`allan_deviation`
    takes: the ``dt`` that makes :func:`white_level` a σ per sample used (equal to
    :func:`sample_interval` on regular samples)."""
    t = np.asarray(t, dtype=float)
    lo, hi = _runs(t, sample_interval(t))
    return float((t[hi - 1] - t[lo]) / max(hi - lo - 1, 1))


def allan_deviation(t: np.ndarray, y: np.ndarray, *, quaternion: bool = False) -> list[AllanCurve]:
    """Overlapping Allan deviation per component at octave τ (module docstring).

    The samples are placed on the grid of their median interval τ0 over the longest run
    without an interval over :data:`HOLE_FACTOR` τ0; missing slots (held repeats left
    out) are empty, and the curve is normalized so that white noise gives
    ``σ sqrt(τ̄/τ)``, τ̄ the mean interval (module docstring). For a quaternion sensor the
    samples are its small angles from the mean attitude (:func:`small_angles`, rad). A
    curve of a sensor's values (not of a rate integrated by the sensor) says something
    about its noise over a still span only.

    Returns one :class:`AllanCurve` per component.
    """
    t = np.asarray(t, dtype=float)
    dt = sample_interval(t)
    lo, hi = _runs(t, dt)
    if quaternion:
        vals = small_angles(np.asarray(y)[lo:hi])
    else:
        vals = np.asarray(y, dtype=float)[lo:hi]
    n = vals.shape[0]
    if n < 2 * MIN_CLUSTERS:
        raise InputError(f"{n} consecutive samples: too few for an Allan deviation")
    tt = t[lo:hi]
    slot = np.rint((tt - tt[0]) / dt).astype(np.int64)
    span = int(slot[-1]) + 1  # grid slots, filled or empty
    tau_bar = mean_interval(t)
    sums = np.zeros((span + 1, vals.shape[1]))
    np.add.at(sums, slot + 1, vals)
    sums = np.cumsum(sums, axis=0)
    counts = np.zeros(span + 1)
    np.add.at(counts, slot + 1, 1.0)
    counts = np.cumsum(counts)
    ms = []
    m = 1
    while span // m >= 2 * MIN_CLUSTERS:
        ms.append(m)
        m *= 2
    taus, avars, pairs = [], [], []
    for m in ms:
        c = counts[m:] - counts[:-m]  # samples in the window starting at each slot
        s = sums[m:] - sums[:-m]
        c1, c2, s1, s2 = c[:-m], c[m:], s[:-m], s[m:]
        good = (c1 > 0) & (c2 > 0)
        if not good.any():
            break
        d = s2[good] / c2[good, None] - s1[good] / c1[good, None]
        h = float(np.mean(0.5 * (1.0 / c1[good] + 1.0 / c2[good])))
        tau = m * dt
        taus.append(tau)
        avars.append(0.5 * np.mean(d * d, axis=0) * tau_bar / (tau * h))
        pairs.append(int(good.sum()))
    av = np.array(avars)
    return [AllanCurve(np.array(taus), np.sqrt(av[:, c]), np.array(pairs)) for c in range(vals.shape[1])]


def gyro_terms(curve: AllanCurve) -> GyroTerms:
    """N, K and B of a gyro axis read off its Allan curve (module docstring)."""
    tau, adev = curve.tau, curve.adev
    slope = curve.slope()
    n_line = adev * np.sqrt(tau)  # N if the −1/2 slope held at τ
    k_line = adev * np.sqrt(3.0 / tau)  # K if the +1/2 slope held at τ
    half = max(1, (tau.size + 1) // 2)
    i = int(np.argmin(np.abs(slope[:half] + 0.5)))  # on the −1/2 slope, short τ
    j = int(np.argmin(k_line))
    b = int(np.argmin(adev))
    return GyroTerms(
        arw=float(n_line[i]),
        arw_tau=float(tau[i]),
        arw_bound=bool(abs(slope[i] + 0.5) > SLOPE_TOLERANCE),
        rrw=float(k_line[j]),
        rrw_tau=float(tau[j]),
        rrw_bound=bool(abs(slope[j] - 0.5) > SLOPE_TOLERANCE),
        bias_instability=float(adev[b] / BIAS_INSTABILITY_FACTOR),
        bias_tau=float(tau[b]),
    )


@dataclass(frozen=True)
class SensorNoise:
    """What one sensor's telemetry shows.

    Attributes
    ----------
    name, type : the sensor.
    components : names of the components; unit : their unit (rad for a quaternion
        sensor's small angles).
    dt : median sample interval [s]; n : samples used.
    white : (m,) per-sample noise σ (robust second differences).
    line : (m,) the white-noise line as a per-sample σ (:func:`white_level`).
    curves : one :class:`AllanCurve` per component.
    gyro : per-axis :class:`GyroTerms` (gyros only), else ().
    stated : the data book's noise figure per sample (None if it gives none).
    mean_dt : mean interval of the samples used [s] (:func:`mean_interval`; above ``dt``
        when they are irregularly spaced): ``line`` is per sample used at this interval.
    """

    name: str
    type: str
    components: tuple[str, ...]
    unit: str
    dt: float
    n: int
    white: np.ndarray
    line: np.ndarray
    curves: tuple[AllanCurve, ...]
    gyro: tuple[GyroTerms, ...]
    stated: float | None
    mean_dt: float = float("nan")


#: telemetry columns per sensor type whose noise is measured here, and their unit
NOISE_COLUMNS = {
    "magnetometer": (("bx", "by", "bz"), "nT"),
    "gyro": (("wx", "wy", "wz"), "rad/s"),
    "attitude_reference": (("q1", "q2", "q3", "q4"), "rad"),
    "fine_sun": (("n_alpha", "n_beta"), "counts"),
    "coarse_sun": (("n_alpha", "n_beta"), "counts"),
}


def sensor_noise(
    name: str,
    stype: str,
    t: np.ndarray,
    table_columns,
    *,
    stated: float | None = None,
    start: float | None = None,
    end: float | None = None,
) -> SensorNoise | None:
    """The noise one sensor's telemetry shows, over ``[start, end]`` (all by default).

    ``table_columns`` maps column name -> (N,) array. Returns None for a type whose
    samples are not one measured quantity followed in time (horizon crossing times,
    plane-field angles, star-tracker angles of a different star at each frame).
    """
    if stype not in NOISE_COLUMNS:
        return None
    cols, unit = NOISE_COLUMNS[stype]
    t = np.asarray(t, dtype=float)
    keep = np.ones(t.size, dtype=bool)
    if start is not None:
        keep &= t >= start
    if end is not None:
        keep &= t <= end
    t = t[keep]
    y = np.column_stack([np.asarray(table_columns[c], dtype=float)[keep] for c in cols])
    quat = stype == "attitude_reference"
    white = white_noise(t, y, quaternion=quat)
    curves = tuple(allan_deviation(t, y, quaternion=quat))
    comps = ("x", "y", "z") if quat else cols
    gyro = tuple(gyro_terms(c) for c in curves) if stype == "gyro" else ()
    dt = sample_interval(t)
    mean_dt = mean_interval(t)
    line = np.array([white_level(c, mean_dt)[0] for c in curves])  # per sample used
    return SensorNoise(name, stype, comps, unit, dt, int(t.size), white, line, curves, gyro, stated, mean_dt)


def mission_noise(mission, *, start: float | None = None, end: float | None = None) -> list[SensorNoise]:
    """:func:`sensor_noise` of every sensor of an imported mission, in mission order."""
    out = []
    for s in mission.spec.sensors:
        tab = mission.telemetry.get(s.name)
        if tab is None or len(tab) < 3:
            continue
        stated = s.noise
        if s.type == "gyro" and s.get("arw") is not None:
            dt = sample_interval(tab.t)
            stated = float(s.get("arw")) / np.sqrt(dt)  # per-sample σ of the ARW
        res = sensor_noise(s.name, s.type, tab.t, tab.columns, stated=stated, start=start, end=end)
        if res is not None:
            out.append(res)
    return out


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def noise_lines(results: list[SensorNoise]) -> list[str]:
    """A plain-text table per sensor: the white noise against the data book's figure, the
    Allan curve at octave τ and, for gyros, N, K and B (``gcs noise``)."""
    out: list[str] = []
    for r in results:
        stated = "none" if r.stated is None else _fmt(r.stated)
        rms = float(np.sqrt(np.mean(r.white**2)))
        white_unit = r.unit
        irregular = np.isfinite(r.mean_dt) and abs(r.mean_dt / r.dt - 1.0) > 0.05
        out.append(
            f"{r.name} ({r.type}), {r.n} samples every {r.dt:.6g} s"
            + (f" (median; {r.mean_dt:.6g} s on average: irregular, σ per sample used)" if irregular else "")
        )
        lr = float(np.sqrt(np.mean(r.line**2)))
        out.append(
            f"  per-sample spread [{white_unit}] (second differences): "
            + "  ".join(f"{c} {_fmt(w)}" for c, w in zip(r.components, r.white))
            + f"  (RMS {_fmt(rms)}; data book {stated}"
            + (f", ratio {rms / r.stated:.3f})" if r.stated else ")")
        )
        note = (
            "above the spread: consecutive samples are correlated, or the values move "
            "(over a still span, this is the noise slow parameters see)"
            if rms < 0.7 * lr
            else "agrees with the spread: white"
        )
        out.append(
            f"  white-noise line as per-sample σ [{white_unit}]: "
            + "  ".join(f"{c} {_fmt(w)}" for c, w in zip(r.components, r.line))
            + f"  (RMS {_fmt(lr)}"
            + (f", ratio to the data book {lr / r.stated:.3f}" if r.stated else "")
            + f"; {note})"
        )
        out.append(f"  Allan deviation [{r.unit}] (overlapping, IEEE 952 Annex C):")
        out.append("    " + f"{'tau [s]':>10}" + "".join(f"{c:>12}" for c in r.components))
        for k in range(r.curves[0].tau.size):
            out.append("    " + f"{r.curves[0].tau[k]:>10.4g}" + "".join(f"{_fmt(c.adev[k]):>12}" for c in r.curves))
        for c, g in zip(r.components, r.gyro):
            out.append(
                f"  {c}: ARW N = {_fmt(g.arw)} rad/s^0.5 (at {g.arw_tau:.3g} s"
                + (", upper bound: no -1/2 slope" if g.arw_bound else "")
                + ")"
                + f"; RRW K = {_fmt(g.rrw)} rad/s^1.5 (at {g.rrw_tau:.3g} s"
                + (", upper bound: no +1/2 slope" if g.rrw_bound else "")
                + ")"
                + f"; bias instability B = {_fmt(g.bias_instability)} rad/s (min at {g.bias_tau:.3g} s)"
            )
    return out


def noise_estimated(toml_text: str, name: str) -> bool:
    """True when the ``[[sensor]]`` block named ``name`` in the mission.toml text marks a
    noise key (:data:`NOISE_KEYS`) with :data:`ESTIMATED_MARK`, in the key's own comment or
    in the comment lines directly above it."""
    import re

    head = re.compile(r'^\s*name\s*=\s*"' + re.escape(name) + r'"')
    key = re.compile(r"^\s*(" + "|".join(NOISE_KEYS) + r")\s*=")
    lines = toml_text.splitlines()
    start = next((i for i, ln in enumerate(lines) if head.match(ln)), None)
    if start is None:
        return False
    for i in range(start + 1, len(lines)):
        if lines[i].lstrip().startswith("["):
            break
        if not key.match(lines[i]):
            continue
        if ESTIMATED_MARK in lines[i]:
            return True
        j = i - 1
        while j > start and lines[j].lstrip().startswith("#"):
            if ESTIMATED_MARK in lines[j]:
                return True
            j -= 1
    return False
