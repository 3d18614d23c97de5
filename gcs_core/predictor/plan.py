"""Data modeling for the predictor (seed §4.3): *when* each sensor has data.

The seed's predictor needs no data, "only a scheme to specify the times at which the
data is available", and "a simple data modeling method which assumes continuous data
segments interleaved with specified data gaps is usually adequate" (§4.3). A
:class:`DataPlan` is that scheme:

* the span ``[start, end]`` and the output step of the σ history;
* data gaps ``[t0, t1)`` in which no observation sensor delivers a frame;
* maneuvers (Eq 4-35, 4-36): over ``[t_m, t_m + D]`` one Euler angle of the nominal
  attitude relative to the reference frame changes at a constant rate,
  ``φ = φ0 + φ̇ (t − t_m)`` (roll; pitch and yaw alike), and holds its new value after;
* per-sensor cadences (otherwise taken from the telemetry, a ``cadence`` data-book key,
  or 1 s — 10 s for star trackers);
* the nominal roll/pitch/yaw at ``start`` (or the spin rate of a spinner);
* the star model of the tracker frames (which star each frame identifies,
  :mod:`gcs_core.predictor.stars`): a star catalog file, the stars of the mission's own
  tracker telemetry, a synthetic sky, or stars spread evenly over the field.

Gaps are telemetry gaps of the *observation* sensors. The gyro, which carries the
attitude between observations (Eq 4-38), is taken to run through them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from gcs_core import limits
from gcs_core.config_checks import AXES, STAR_MODELS
from gcs_core.config_schema import AnalysisConfig, Maneuver
from gcs_core.errors import InputError
from gcs_core.units import DEG

#: default cadence [s] when neither the plan, the telemetry nor the data book gives one
DEFAULT_CADENCE_S = 1.0
#: default cadence of star trackers [s] (one identified star every 10 s)
DEFAULT_TRACKER_CADENCE_S = 10.0
FRAME_SOURCES = ("plan", "telemetry")


@dataclass(frozen=True)
class DataPlan:
    """A data plan for the predictor (module docstring).

    Attributes
    ----------
    start, end : plan span [s since the mission epoch].
    step : spacing of the output times of the σ history [s].
    gaps : ``(t0, t1)`` intervals without observation data.
    maneuvers : constant-rate Euler-angle maneuvers (Eq 4-36), from :mod:`gcs_core.config`.
    cadence : sensor name -> frame spacing [s], overriding telemetry and data book.
    rpy0 : nominal roll, pitch, yaw at ``start`` [rad] relative to the reference frame;
        None: from the onboard attitude at ``start`` if there is one, else zeros.
    spin_rate : spin rate of a spinning mission [rad/s]; None: from the horizon
        telemetry or the data-book key ``spin_rate_rpm``.
    frames : ``"plan"`` — generate the frame times from the cadences, the gaps and the
        sensor availability; ``"telemetry"`` — use the telemetry's own frame times and
        star identifications (values ignored), minus the gaps.
    stars : star-tracker headers (:data:`~gcs_core.config.STAR_MODELS`), the stars the
        nominal boresight sweeps, one per frame drawn ∝ brightness: ``"catalog"`` — of
        the star catalog ``catalog`` (CSV ``ra, dec, mag``); ``"telemetry"`` — the
        distinct stars identified in the mission's tracker telemetry; ``"sky"`` — of a
        fixed synthetic sky (right on average, but a still pointing's σ of the scale
        factors depends on exactly which stars are in the field); ``"uniform"`` — one
        star per frame spread evenly over the field of view (no catalog at all).
    catalog : the star catalog file of ``stars = "catalog"``; a relative path is taken
        from the mission directory; None: the mission's ``star_catalog.csv``.
    sensor_gaps : sensor name -> its own ``(t0, t1)`` gaps, on top of ``gaps`` (a plan's
        ``[[sensor]] gaps``: a tracker blinded by the Earth, a Sun sensor switched off).
    """

    start: float
    end: float
    step: float = 10.0
    gaps: tuple[tuple[float, float], ...] = ()
    maneuvers: tuple[Maneuver, ...] = ()
    cadence: Mapping[str, float] = field(default_factory=dict)
    rpy0: tuple[float, float, float] | None = None
    spin_rate: float | None = None
    frames: str = "plan"
    stars: str = "sky"
    catalog: Path | None = None
    sensor_gaps: Mapping[str, tuple[tuple[float, float], ...]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start) and math.isfinite(self.end) and self.end > self.start):
            raise InputError(f"the plan needs end > start (got {self.start}, {self.end})", key="prediction.end")
        if not self.step > 0:
            raise InputError(f"must be > 0, got {self.step}", key="prediction.step")
        if (self.end - self.start) / self.step + 1 > limits.MAX_OUTPUT_TIMES:  # before any allocation
            raise InputError(
                f"{self.step:g} s gives {(self.end - self.start) / self.step + 1:.3g} output times over the plan; "
                f"at most {limits.MAX_OUTPUT_TIMES} (a larger step)",
                key="prediction.step",
            )
        for g in self.gaps:
            if len(g) != 2 or not g[0] < g[1]:
                raise InputError(f"a gap must be [t0, t1] with t0 < t1, got {g!r}", key="prediction.gaps")
        for name, gs in self.sensor_gaps.items():
            for g in gs:
                if len(g) != 2 or not g[0] < g[1]:
                    raise InputError(f"a gap must be [t0, t1] with t0 < t1, got {g!r}", key=f"{name}.gaps")
        for i, m in enumerate(self.maneuvers):
            if m.axis not in AXES:
                raise InputError(f"axis must be one of {', '.join(AXES)}", key=f"prediction.maneuvers[{i}].axis")
            if not m.duration > 0:
                raise InputError("duration must be > 0", key=f"prediction.maneuvers[{i}].duration")
        for name, c in self.cadence.items():
            if not c > 0:
                raise InputError(f"cadence must be > 0, got {c}", key=f"cadence.{name}")
        if self.stars not in STAR_MODELS:
            raise InputError(f"stars must be one of {', '.join(STAR_MODELS)}", key="prediction.stars")
        if self.catalog is not None:
            if self.stars != "catalog":
                raise InputError(f'a catalog goes with stars = "catalog", not {self.stars!r}', key="prediction.catalog")
            if not str(self.catalog).strip():
                raise InputError("must be the star catalog file, not an empty name", key="prediction.catalog")
            object.__setattr__(self, "catalog", Path(self.catalog))
        if self.frames not in FRAME_SOURCES:
            raise InputError(f"frames must be one of {', '.join(FRAME_SOURCES)}", key="prediction.frames")

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_config(cls, cfg: AnalysisConfig, *, span: tuple[float, float] | None = None, **overrides) -> DataPlan:
        """The plan of an analysis config's ``[prediction]`` table.

        ``span`` supplies start/end where the config leaves them out (e.g. the
        telemetry span); keyword ``overrides`` replace any field. A config that names a
        catalog but no star model means ``stars = "catalog"``.
        """
        start, end = cfg.prediction.start, cfg.prediction.end
        if start is None or end is None:
            if span is None:
                raise InputError(
                    "the plan needs prediction.start and prediction.end (no telemetry span to default to)",
                    file=cfg.path,
                    key="prediction.start",
                )
            start = span[0] if start is None else start
            end = span[1] if end is None else end
        kw: dict[str, Any] = dict(
            start=float(start),
            end=float(end),
            step=cfg.prediction.step,
            gaps=tuple(cfg.prediction.gaps),
            maneuvers=tuple(cfg.prediction.maneuvers),
        )
        stars = cfg.prediction.stars or ("catalog" if cfg.prediction.catalog is not None else None)
        if stars is not None:
            kw["stars"] = stars
        if cfg.prediction.catalog is not None:
            kw["catalog"] = Path(cfg.prediction.catalog)
        kw.update(overrides)
        if kw.get("stars", "sky") != "catalog" and "catalog" not in overrides and "stars" in overrides:
            kw.pop("catalog", None)  # an override to another star model drops the file
        try:
            return cls(**kw)
        except InputError as err:
            if err.file is None and err.key is not None and err.key.startswith("prediction."):
                raise replace(err, file=cfg.path) from None
            raise

    # ------------------------------------------------------------------ times
    def output_times(self) -> np.ndarray:
        """(T,) ``start, start + step, …`` and ``end`` itself."""
        n = int(math.ceil((self.end - self.start) / self.step - 1e-9))
        t = self.start + self.step * np.arange(n + 1, dtype=float)
        t[-1] = self.end
        return t

    def grid(self, cadence: float, *, first: float | None = None) -> np.ndarray:
        """(N,) frame slots ``first + k·cadence`` inside ``[start, end]`` (``first`` = start)."""
        t0 = self.start if first is None else first
        if (self.end - t0) / cadence + 1 > limits.MAX_PLAN_FRAMES:  # before any allocation
            raise InputError(
                f"{(self.end - t0) / cadence + 1:.3g} frames at {cadence:g} s over the plan; "
                f"at most {limits.MAX_PLAN_FRAMES} per sensor (a shorter plan)",
                key="prediction.end",
            )
        n = int(math.floor((self.end - t0) / cadence + 1e-9))
        return t0 + cadence * np.arange(n + 1, dtype=float)

    def in_gap(self, t, sensor: str | None = None) -> np.ndarray:
        """(N,) True where ``t`` lies in a data gap ``[t0, t1)`` (with ``sensor``: in one of
        the plan's gaps or that sensor's own)."""
        t = np.asarray(t, dtype=float)
        mask = np.zeros(t.shape, dtype=bool)
        for a, b in (*self.gaps, *self.sensor_gaps.get(sensor or "", ())):
            mask |= (t >= a) & (t < b)
        return mask

    def in_span(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return (t >= self.start) & (t <= self.end)

    # ------------------------------------------------------------------ maneuvers
    def maneuver_offsets(self, t) -> np.ndarray:
        """Eq 4-36: (N, 3) change of roll, pitch, yaw [rad] since ``start``.

        Each maneuver adds ``φ̇ · clip(t − t_m, 0, D)`` to its axis: a constant rate
        during the maneuver, the angle held after it.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.zeros((t.size, 3))
        for m in self.maneuvers:
            k = AXES.index(m.axis)
            rate = m.rate_deg_s * DEG
            out[:, k] += rate * (np.clip(t - m.start, 0.0, m.duration) - np.clip(self.start - m.start, 0.0, m.duration))
        return out
