"""Generate the bundled sample data: ``python -m gcs_core.sim.samples OUT_DIR``.

Writes ``OUT_DIR/missions/<name>/`` (ICD mission directories, each about 1.3 MB) and the
answer files ``OUT_DIR/answers/<name>.json`` (truth.json: true parameters and the hidden
effects). All data carry the real always-on physics (stellar and solar aberration, solar
parallax, the WGS-84 horizon crossed exactly), as a real spacecraft's would. The samples:

=========================  ===========================================================
nominal-sunpoint           Sun-pointing, 2 h at 1 Hz, data book = truth
hidden-tam-contamination   TAM1 reads 0.5 nT per A m² of mtb_x (``TAM1.contamination_mtb_x``)
hidden-fhst-boresight      FHST1 rotated 0.1° about its boresight (``FHST1.alignment``)
hidden-fss-harmonic        FSS1 second harmonic H sin(2k tan α), H_α = 5e-5, H_β = −4e-5
                           (``FSS1.harmonic``), on a known fundamental A3 = 2e-4, B3 = −1.5e-4;
                           a ±3° pitch/yaw sweep carries the Sun across the FSS
hidden-gyro-scale          IRU G = diag(1 + 1e-3·(1, −0.7, 0.5)) (``IRU.scale_misalignment``)
spinner-hidden-horizon     10 rpm spinner, HS1 cone angle off by 0.25° (``HS1.d_gamma``)
=========================  ===========================================================

Deterministic: the same command gives the same bytes.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from gcs_core.sim.config import MissionConfig
from gcs_core.sim.scenarios import nominal_threeaxis, spinner_nominal, with_effect
from gcs_core.sim.writer import write_mission

log = logging.getLogger("gcs_core.sim.samples")

__all__ = ["SAMPLES", "generate_samples", "main"]


def _sun(seed: int, name: str, sweep_deg: float = 0.0) -> MissionConfig:
    return nominal_threeaxis("sun_pointing", seed=seed, duration_s=7200.0, name=name, sweep_deg=sweep_deg)


def _rippled_fss(cfg: MissionConfig) -> MissionConfig:
    """Give FSS1 a known fundamental ripple (book = truth): A3 = 2e-4, B3 = -1.5e-4.

    With A3 = 0 in the book, the seed term A3 sin(k tan α) with k doubled reproduces a second
    harmonic exactly; a known fundamental pins k and keeps the harmonic a distinct effect.
    """
    s = cfg.sensor("FSS1")
    s.book["coeff_alpha"] = [0.0, 7.6e-05, 2e-4, 50.0]
    s.book["coeff_beta"] = [0.0, 7.6e-05, -1.5e-4, 50.0]
    return cfg


SAMPLES: dict[str, Callable[[], MissionConfig]] = {
    "nominal-sunpoint": lambda: _sun(101, "nominal-sunpoint"),
    "hidden-tam-contamination": lambda: with_effect(
        _sun(102, "hidden-tam-contamination"), "TAM1.contamination_mtb_x", 0.5
    ),
    "hidden-fhst-boresight": lambda: with_effect(
        _sun(103, "hidden-fhst-boresight"),
        "FHST1.alignment",
        math.radians(0.1),
        axis=(1.0, 0.0, 0.0),
        description="FHST1 rotated 0.1 deg about its boresight",
    ),
    "hidden-fss-harmonic": lambda: with_effect(
        _rippled_fss(_sun(104, "hidden-fss-harmonic", sweep_deg=3.0)), "FSS1.harmonic", 5e-5
    ),
    "hidden-gyro-scale": lambda: with_effect(
        _sun(105, "hidden-gyro-scale"),
        "IRU.scale_misalignment",
        1e-3,
        pattern=np.diag([1.0, -0.7, 0.5]),
        description="IRU scale factors 1 + 1e-3 (1, -0.7, 0.5): G diagonal",
    ),
    "spinner-hidden-horizon": lambda: with_effect(
        spinner_nominal(106, name="spinner-hidden-horizon"), "HS1.d_gamma", math.radians(0.25)
    ),
}


def generate_samples(out_dir, names=None) -> list[Path]:
    """Write the samples (all, or ``names``) under ``out_dir``; returns the mission directories."""
    out_dir = Path(out_dir)
    done = []
    for name in names or SAMPLES:
        cfg = SAMPLES[name]()
        path = write_mission(cfg, out_dir / "missions" / name, truth_path=out_dir / "answers" / f"{name}.json")
        log.info("wrote %s", path)
        done.append(path)
    return done


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gcs_core.sim.samples", description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", help="where to write missions/ and answers/ (e.g. sample_data)")
    parser.add_argument("--only", nargs="*", choices=sorted(SAMPLES), help="generate only these samples")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    generate_samples(args.out_dir, args.only)
    return 0


if __name__ == "__main__":
    sys.exit(main())
