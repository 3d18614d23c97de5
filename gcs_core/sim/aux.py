"""Auxiliary channels (ICD §6): torquer dipoles and magnetometer temperature.

Torquer dipoles ``mtb_x, mtb_y, mtb_z`` [A m²] are piecewise constant: each channel
switches to a level drawn from ``mtb_levels`` after a dwell uniform in ``mtb_dwell_s``;
switch times are multiples of the aux cadence so that the rows of aux.csv (a channel
holds its value until its next row) describe the truth exactly.

``tam_temp`` [°C] is a slow sinusoid ``T0 + ΔT sin(2π t / P)``, written rounded to 1e-4.

``iru_heater`` (0 or 1), only when :attr:`AuxConfig.heater` is set: the IRU's heater, a
thermostat's duty cycle (:func:`gcs_core.sim.drifts.thermostat`), drawn from its own random
stream so that the other channels are those of the same mission without it.
"""

from __future__ import annotations

import numpy as np

from gcs_core.sim.config import AuxConfig
from gcs_core.sim.drifts import thermostat

MTB_CHANNELS = ("mtb_x", "mtb_y", "mtb_z")
#: the IRU heater's on/off channel (with ``AuxConfig.heater``)
HEATER = "iru_heater"

__all__ = ["AuxSchedule", "MTB_CHANNELS"]


class AuxSchedule:
    """Switch schedule of the torquers over the whole mission (small: a few per hour)."""

    columns: tuple[str, ...] = ("t",) + MTB_CHANNELS + ("tam_temp",)
    formats: tuple[str, ...] = ("%.12g",) * 5

    def __init__(
        self, cfg: AuxConfig, duration_s: float, rng: np.random.Generator, heater_rng: np.random.Generator | None = None
    ):
        self.cfg = cfg
        self.switch_t: dict[str, np.ndarray] = {}
        self.level: dict[str, np.ndarray] = {}
        step = cfg.cadence_s
        for ch in MTB_CHANNELS:
            times, levels = [0.0], [float(rng.choice(cfg.mtb_levels))]
            t = 0.0
            while True:
                t += np.round(rng.uniform(*cfg.mtb_dwell_s) / step) * step
                if t > duration_s:
                    break
                times.append(float(t))
                levels.append(float(rng.choice([x for x in cfg.mtb_levels if x != levels[-1]])))
            self.switch_t[ch] = np.asarray(times)
            self.level[ch] = np.asarray(levels)
        self.temp_phase = float(rng.uniform(0, 2 * np.pi))
        if cfg.heater:
            hr = heater_rng if heater_rng is not None else np.random.default_rng(0)
            sw = thermostat(duration_s, step, cfg.temp_period_s, hr)
            self.switch_t[HEATER] = sw
            self.level[HEATER] = (np.arange(sw.size) % 2).astype(float)  # off, on, off, ...
            self.columns = AuxSchedule.columns + (HEATER,)
            self.formats = AuxSchedule.formats + ("%.12g",)

    def value(self, channel: str, t) -> np.ndarray:
        """True value of a channel at times ``t`` (N,)."""
        t = np.asarray(t, dtype=float)
        if channel == "tam_temp":
            c = self.cfg
            raw = c.temp_mean_c + c.temp_amp_c * np.sin(2 * np.pi * t / c.temp_period_s + self.temp_phase)
            return np.round(raw, 4)
        k = np.searchsorted(self.switch_t[channel], t, side="right") - 1
        return self.level[channel][np.clip(k, 0, None)]

    def rows(self, t_rows: np.ndarray) -> dict[str, np.ndarray]:
        out = {"t": t_rows}
        for ch in self.columns[1:]:
            out[ch] = self.value(ch, t_rows)
        return out
