"""The correlation-robust σ of ``gcs batch``/``discover`` over seeds, against truth.

The laboratory mission of ``tests/statistical/test_sigma_scale_report.py`` (exact
kinematics, a field gradient, 60 s at 50 Hz), fitted as the product fits it and scored
over 1-s windows (60) as ``--sigma-window 1`` does: per seed, the range of the
magnetometer's and the field's scales (√10 = 3.16 expected with each draw held over 10
samples, 1 with white noise), whether the state table adds its block (it must on held
noise, never on white), and the worst and RMS |z| of those elements against the truth with
the fit's σ and with σ × max(1, s).

    python benchmarks/sigma_scale_report.py [--seeds 20 26]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), *(str(p) for p in sorted((ROOT / "tests").iterdir()) if p.is_dir())]

from test_field_gradient import EFFECTS, fit, write_mission
from test_sigma_scale import MAG_ELEMENTS, _truth

from gcs_tui.cli.tables import HEADER_SIGMA_SCALE, state_table

WINDOW_S = 1.0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", nargs=2, type=int, default=(20, 26), metavar=("FIRST", "END"))
    args = p.parse_args()
    for hold in (1, 10):
        for seed in range(*args.seeds):
            with tempfile.TemporaryDirectory() as tmp:
                root = write_mission(Path(tmp), np.random.default_rng(seed), hold=hold)
                a, res = fit(root, EFFECTS + ("MAG.field_gradient",))
                a.sigma_window = WINDOW_S
                sc = a.sigma_scale()
                block = any(line.startswith(HEADER_SIGMA_SCALE) for line in state_table(a))
            s = [sc.scale[n] for n in MAG_ELEMENTS]
            v, honest = res.state.values(), sc.honest_sigma(res.sigma)
            z = np.array([abs(v[n] - x) / honest[n] for n, x in _truth().items()])
            zf = np.array([abs(v[n] - x) / res.sigma[n] for n, x in _truth().items()])
            print(
                f"hold {hold:2d} seed {seed}: scales {min(s):.2f}-{max(s):.2f} ({sc.n_blocks} windows), "
                f"table block {'yes' if block else 'no'}; |z| worst {zf.max():.2f} fit σ, {z.max():.2f} "
                f"σ × max(1, s); RMS z {np.sqrt(np.mean(zf**2)):.2f}, {np.sqrt(np.mean(z**2)):.2f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
