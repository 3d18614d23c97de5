"""The ``gcs`` command: the TUI and the headless runs from one config.

Commands (``gcs COMMAND --help`` for options):

* ``gcs tui [TARGET]`` — the analyst's terminal UI;
* ``gcs import MISSION [--sdf FILE]`` — validate a mission directory, write the SDF;
* ``gcs batch TARGET`` — fit the configured state, print residuals and estimates;
* ``gcs discover TARGET`` — stepwise missing-effect discovery;
* ``gcs effects [TARGET]`` — the catalogue of candidate effects;
* ``gcs predict TARGET`` — covariance-only accuracy prediction for the data plan;
* ``gcs verify TARGET`` — onboard against ground attitudes, §4.4 flag.

``TARGET`` is an analysis config (``.toml``) or a mission directory (default config).

Exit codes: 0 success; 1 the run completed and found something the analyst must act
on (``verify`` raised the §4.4 flag; ``discover`` added effects with ``--strict``);
2 bad input (the message names the file, line and column or the key); 3 the
estimation failed (divergence, unobservable state); 130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path

from gcs_core.errors import EstimationError, GcsError, InputError

log = logging.getLogger("gcs")

EXIT_OK, EXIT_FLAG, EXIT_INPUT, EXIT_ESTIMATION, EXIT_INTERRUPT = 0, 1, 2, 3, 130


def _out(text: str = "") -> None:
    sys.stdout.write(text + "\n")


def _load(target: str):
    from gcs_core.config import default_config, load_config

    p = Path(target)
    if p.is_dir():
        return default_config(p)
    if p.suffix == ".toml" or p.is_file():
        return load_config(p)
    raise InputError("no such mission directory or config file", file=p)


def _analysis(args):
    from gcs_core.session import Analysis

    cfg = _load(args.target)
    if getattr(args, "method", None):
        from dataclasses import replace
        cfg = replace(cfg, method=args.method)
    return Analysis(cfg)


def _write_json(path: str | None, data: dict) -> None:
    if not path:
        return
    from gcs_core.reporting import write_json_atomic
    write_json_atomic(Path(path), data)
    log.info("report written to %s", path)


# ---------------------------------------------------------------------------- commands
def cmd_tui(args) -> int:
    from gcs_tui.app import run_tui

    run_tui(args.target)
    return EXIT_OK


def cmd_import(args) -> int:
    from gcs_core.sidp.importer import load_mission

    m = load_mission(args.mission)
    rep = m.report
    _out(f"mission {m.spec.name}: {len(m.spec.sensors)} sensors, attitude mode {m.spec.attitude_mode}")
    for line in rep.lines() if hasattr(rep, "lines") else [str(rep)]:
        _out("  " + line)
    if args.sdf:
        from gcs_core.sidp.sdf import write_sdf
        write_sdf(Path(args.sdf), m)
        _out(f"SDF written to {args.sdf}")
    return EXIT_OK


def _print_fit(a) -> None:
    from gcs_core.reporting import fit_table, state_table

    for line in fit_table(a):
        _out(line)
    _out("")
    for line in state_table(a):
        _out(line)


def cmd_batch(args) -> int:
    a = _analysis(args)
    _progress(args, f"fitting {a.mission.spec.name} ({a.config.method})")
    a.fit()
    if args.rank:
        a.rank()
    _print_fit(a)
    if args.scds:
        from gcs_core.calibration import save_calibration
        v = save_calibration(a, Path(args.scds), note=args.note or "")
        _out(f"calibration saved as version {v} in {args.scds}")
    _write_json(args.report, a.report())
    _export_plots(args, a)
    return EXIT_OK


def cmd_discover(args) -> int:
    from dataclasses import replace

    a = _analysis(args)
    if args.significance:
        a.config = replace(a.config, significance=args.significance)
    steps = a.discover(max_steps=args.max_steps, progress=lambda m: _progress(args, m))
    _print_fit(a)
    added = [s.effect for s in steps if s.action == "add"]
    _out("")
    _out("effects added: " + (", ".join(added) if added else "none"))
    for s in steps:
        if s.action == "add":
            cand = next((c for c in a.steps if c is s), None)
            _out(f"  {s.effect}: Δχ² {s.delta_chi2:.1f}; normalized RMS after: "
                 + ", ".join(f"{k} {v:.3f}" for k, v in s.rms_after.items()))
    _out("stopped: " + a.stop_reason)
    _write_json(args.report, a.report())
    _export_plots(args, a)
    return EXIT_FLAG if (args.strict and added) else EXIT_OK


def cmd_effects(args) -> int:
    from gcs_core.diagnosis.catalogue import generic_catalogue

    if args.target:
        a = _analysis(args)
        in_state = set(a.effects_in_state())
        _out(f"{'effect id':38s} {'family':18s} in state")
        for e in a.catalogue():
            _out(f"{e.id:38s} {e.family:18s} {'yes' if e.id in in_state else 'no'}")
        return EXIT_OK
    for name, family, text in generic_catalogue():
        _out(f"<SENSOR>.{name}" if family != "physics" else f"model.{name}")
        _out(f"    [{family}] {text}")
    return EXIT_OK


def cmd_predict(args) -> int:
    from gcs_core.predictor import predict
    from gcs_core.reporting import prediction_table

    cfg = _load(args.target)
    res = predict(cfg)
    for line in prediction_table(res):
        _out(line)
    _write_json(args.report, res.as_report() if hasattr(res, "as_report") else {})
    return EXIT_OK


def cmd_verify(args) -> int:
    from gcs_core.verif import verify_analysis

    a = _analysis(args)
    a.fit(holdout=False)
    v = verify_analysis(a)
    _out(v.summary() if hasattr(v, "summary") else str(v))
    if args.asf:
        from gcs_core.calibration import save_ground_attitude
        save_ground_attitude(a, Path(args.asf))
    _write_json(args.report, v.as_report() if hasattr(v, "as_report") else {})
    return EXIT_FLAG if v.flag else EXIT_OK


def _progress(args, message: str) -> None:
    log.info(message)


def _export_plots(args, a) -> None:
    if not getattr(args, "plots", None):
        return
    from gcs_tui.export import export_residual_plots
    paths = export_residual_plots(a, Path(args.plots), fmt=args.plot_format)
    _out(f"{len(paths)} plots written to {args.plots}")


# ---------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gcs", description="GCS: calibrate and verify spacecraft attitude sensors")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="command", required=True)

    def target(sp, required=True):
        sp.add_argument("target", nargs=None if required else "?",
                        help="analysis config (.toml) or mission directory")

    sp = sub.add_parser("tui", help="the analyst's terminal UI")
    sp.add_argument("target", nargs="?", default="sample_data/missions/hidden-tam-contamination")
    sp.set_defaults(func=cmd_tui)

    sp = sub.add_parser("import", help="validate a mission directory and write the SDF")
    sp.add_argument("mission")
    sp.add_argument("--sdf", help="write the Standard Data File (HDF5) here")
    sp.set_defaults(func=cmd_import)

    for name, func, helptext in (("batch", cmd_batch, "fit the configured state"),
                                 ("discover", cmd_discover, "stepwise missing-effect discovery")):
        sp = sub.add_parser(name, help=helptext)
        target(sp)
        sp.add_argument("--report", help="write the JSON report (ICD §7) here")
        sp.add_argument("--method", choices=("batch", "kalman"), help="override the config's method")
        sp.add_argument("--plots", help="export residual plots to this folder")
        sp.add_argument("--plot-format", choices=("txt", "html"), default="txt")
        if name == "batch":
            sp.add_argument("--rank", action="store_true", help="also rank candidate effects")
            sp.add_argument("--scds", help="append the calibration to this SCDS (HDF5)")
            sp.add_argument("--note", help="note stored with the calibration")
        else:
            sp.add_argument("--max-steps", type=int, default=10)
            sp.add_argument("--significance", type=float, help="family-wise α (default from config)")
            sp.add_argument("--strict", action="store_true", help="exit 1 when effects were added")
        sp.set_defaults(func=func)

    sp = sub.add_parser("effects", help="list the catalogue of candidate effects")
    target(sp, required=False)
    sp.set_defaults(func=cmd_effects)

    sp = sub.add_parser("predict", help="covariance-only prediction for the data plan")
    target(sp)
    sp.add_argument("--report", help="write a JSON report here")
    sp.set_defaults(func=cmd_predict)

    sp = sub.add_parser("verify", help="onboard vs ground attitude, §4.4 flag")
    target(sp)
    sp.add_argument("--report", help="write a JSON report here")
    sp.add_argument("--asf", help="append the ground attitudes to this Attitude Status File")
    sp.set_defaults(func=cmd_verify)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="gcs: %(message)s", stream=sys.stderr)
    logging.getLogger("matplotlib").setLevel(logging.WARNING)
    try:
        return args.func(args)
    except InputError as err:
        sys.stderr.write(f"gcs: error: {err}\n")
        return EXIT_INPUT
    except EstimationError as err:
        sys.stderr.write(f"gcs: estimation failed: {err}\n")
        return EXIT_ESTIMATION
    except GcsError as err:
        sys.stderr.write(f"gcs: error: {err}\n")
        return EXIT_INPUT
    except KeyboardInterrupt:
        sys.stderr.write("gcs: interrupted\n")
        return EXIT_INTERRUPT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
