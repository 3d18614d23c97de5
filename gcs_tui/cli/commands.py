"""The ``gcs`` command: the TUI and the headless runs from one config.

Commands (``gcs COMMAND --help`` for options):

* ``gcs tui [TARGET]`` — the analyst's terminal UI;
* ``gcs convert FORMAT SOURCE --out DIR [--tle TLE]`` — foreign data (``astropi``,
  ``broad``) to a mission directory (:mod:`gcs_core.convert`);
* ``gcs import MISSION [--sdf FILE] [--report R]`` — validate a mission directory, print what
  was read (rows kept, NaN and duplicate rows dropped per file, unknown keys), write the SDF;
* ``gcs batch TARGET`` — fit the configured state, print residuals and estimates;
* ``gcs discover TARGET`` — stepwise missing-effect discovery;
* ``gcs effects [TARGET]`` — the catalogue of candidate effects (generic, or the mission's);
* ``gcs predict TARGET`` — covariance-only accuracy prediction for the data plan;
* ``gcs verify TARGET`` — onboard against ground attitudes, §4.4 flag;
* ``gcs trade``, ``gcs optimize``, ``gcs montecarlo`` — plan before launch
  (:mod:`gcs_tui.cli.trade`);
* ``gcs fleet MANIFEST``, ``gcs fleet-sim OUT`` — a fleet's daily calibration on Dask
  (:mod:`gcs_tui.cli.fleet`).

``TARGET`` is an analysis config (``.toml``, see :mod:`gcs_core.config` and
``sample_data/configs/``) or a mission directory (default config). ``--report R`` writes
the JSON report (ICD §7 for ``batch`` and ``discover``); ``--plots DIR`` exports residual
plots (``--plot-format txt|html``).

Results go to stdout; progress, log lines and errors to stderr: a live progress line when
stderr is a terminal, plain ``gcs: ...`` lines otherwise (CI, pipes), nothing with ``-q``
(:mod:`gcs_tui.cli.progress`).

Exit codes: 0 success; 1 the run completed and found something the analyst must act
on (``verify`` raised the §4.4 flag; ``discover --strict`` added effects);
2 bad input, one line naming the file, line and column or the config key (also a
usage error); 3 the estimation failed (divergence, unobservable state); 4 an internal
error (a bug in GCS: one line, ``-v`` shows the traceback); 130 interrupted.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import traceback
import warnings
from pathlib import Path

# GCS's matrices are small (tens of columns): threaded BLAS only contends for the cores,
# by 10-50x on a loaded 2-core machine. Set before numpy loads; the user's value wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from gcs_core.config_checks import NOISE_WEIGHTINGS
from gcs_core.errors import ConfigError, EstimationError, GcsError, InputError
from gcs_core.textsafe import terminal_safe
from gcs_tui.cli.arguments import seconds_or_zero, whole_number
from gcs_tui.cli.outputs import check_outputs
from gcs_tui.cli.progress import MODES, LogHandler, Progress, warning_line

log = logging.getLogger("gcs")

EXIT_OK, EXIT_FLAG, EXIT_INPUT, EXIT_ESTIMATION, EXIT_INTERNAL, EXIT_INTERRUPT = 0, 1, 2, 3, 4, 130
#: fit statuses that mean the estimation failed (exit 3 after the tables are printed)
FAILED_STATUSES = ("diverged",)
#: loggers the command shows (``gcs`` at INFO, the engine's at WARNING unless ``-v``)
LOGGERS = ("gcs", "gcs_core", "gcs_tui")


def _out(text: str = "") -> None:
    """One result line (or several), control characters from files shown escaped."""
    sys.stdout.write(terminal_safe(text) + "\n")


def _lines(lines) -> None:
    for line in lines:
        _out(line)


# ---------------------------------------------------------------------------- set-up
def _load(args):
    """The analysis config of ``args.target`` (a .toml, or a mission directory's default)."""
    from gcs_core.config import config_for

    cfg = config_for(args.target)
    args.config_path = cfg.path
    if getattr(args, "method", None):
        cfg = cfg.with_changes(method=args.method)
    if getattr(args, "noise_weighting", None):
        cfg = cfg.with_changes(filter={"noise_weighting": args.noise_weighting})
    return cfg


def _setup(args, prog: Progress):
    """(config, imported mission), the config checked against the mission."""
    from gcs_core.config_checks import check_against_mission
    from gcs_core.io.importer import load_mission
    from gcs_core.suggest import did_you_mean_path

    cfg = _load(args)
    with prog.task(f"reading mission {cfg.mission}"):
        if cfg.path is not None and not Path(cfg.mission).is_dir():
            hint = did_you_mean_path(cfg.mission, want_dir=True)
            raise ConfigError(f"no mission directory at {cfg.mission}{hint}", key="analysis.mission", file=cfg.path)
        mission = load_mission(cfg.mission)
    check_against_mission(cfg, mission.spec)
    return cfg, mission


def _analysis(args, prog: Progress):
    from gcs_core.session import Analysis

    cfg, mission = _setup(args, prog)
    with prog.task("building the state"):
        a = Analysis(cfg, mission=mission)
    if getattr(args, "sigma_window", None) is not None:
        a.sigma_window = args.sigma_window
    return a


def _fit(a, prog: Progress, **kw):
    with prog.task(f"fitting {a.mission.spec.name} ({a.config.method})"):
        return a.fit(**kw)


def _fit_failed(a) -> bool:
    res = a.result
    if res is not None and res.status in FAILED_STATUSES:
        sys.stderr.write(f"gcs: estimation failed: {terminal_safe(res.message, one_line=True)}\n")
        return True
    return False


def _write_json(path: str | None, data) -> None:
    """Write the report to ``path`` if one was asked for; ``data`` is the dict or a
    function making it (a report can cost a scoring pass: not made when not written)."""
    if not path:
        return
    if callable(data):
        data = data()
    from gcs_core.reporting import write_json_atomic

    try:
        write_json_atomic(Path(path), data)
    except OSError as err:
        raise InputError(f"cannot write the report ({err.strerror or err})", file=path) from None
    log.info("report written to %s", path)


def _output(path: str) -> Path:
    """An output file's path, its folder created if missing."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"cannot create the folder ({err.strerror or err})", file=p.parent) from None
    return p


def _export_plots(args, a) -> None:
    if not getattr(args, "plots", None):
        return
    from gcs_tui.cli.export import export_residual_plots

    try:
        paths = export_residual_plots(a, Path(args.plots), fmt=args.plot_format)
    except OSError as err:
        raise InputError(f"cannot write the plots ({err.strerror or err})", file=args.plots) from None
    _out(f"{len(paths)} plot file(s) written to {args.plots}")


def _print_fit(a) -> None:
    from gcs_tui.cli.tables import fit_table, state_table

    _lines(fit_table(a))
    _out("")
    _lines(state_table(a))


def _write_noise_correlation(args, a) -> None:
    """``--write-noise-correlation``: each significant measured correlation time into the
    mission's mission.toml (:mod:`gcs_core.io.noise_declaration`)."""
    if not getattr(args, "write_noise_correlation", False):
        return
    from gcs_core.io.noise_declaration import declare

    taus = {
        n: c.tau_s
        for n, c in getattr(a, "correlation", {}).items()
        if c.significant and c.source == "measured" and c.tau_s > 0
    }
    if not taus:
        _out("no measured noise correlation is significant: mission.toml left as it was")
        return
    path = a.mission.spec.root / "mission.toml"
    if not path.is_file():
        _out(f"no mission.toml at {a.mission.spec.root} to declare the noise correlation in")
        return
    declare(path, taus, note="measured from the residuals by gcs")
    _out(f"declared in {path}: " + ", ".join(f"{n} noise_correlation_s = {t:.4g}" for n, t in taus.items()))


# ---------------------------------------------------------------------------- commands
def terminal_problem() -> str:
    """Why the TUI cannot run here ('' when it can): it needs a terminal on stdin, stdout and stderr."""
    # Textual draws on stderr and reads stdin: all three must be the terminal
    for name, stream in (("stdin", sys.stdin), ("stdout", sys.stdout), ("stderr", sys.stderr)):
        try:
            tty = stream is not None and stream.isatty()
        except (AttributeError, ValueError, OSError):
            tty = False
        if not tty:
            return (
                f"gcs tui needs a terminal, but {name} is not one (redirected or piped); "
                "for headless runs use gcs batch, discover, predict or verify"
            )
    return ""


def step_messages(prog: Progress, task):
    """The discovery's message callback: each step once — above the live line and as its text
    on a terminal, one ``gcs: ...`` line in plain mode (not once per channel)."""
    if prog.mode != "bar":
        return prog.message

    def say(message: str) -> None:
        prog.message(message)
        task(text=message)

    return say


def cmd_tui(args, prog: Progress) -> int:
    problem = terminal_problem()
    if problem:  # a full-screen app on a pipe would spin; refuse at once
        raise InputError(problem)
    from gcs_tui.tui.app import run_tui

    app = run_tui(args.target, work_dir=args.out)
    if app.crash_line:  # an unhandled error in the app: one line (the traceback is in a log)
        return _error(prog, app.crash_line, EXIT_INTERNAL)
    return EXIT_OK


def cmd_warmup(args, prog: Progress) -> int:
    """Compile the numerical kernels now, so that the first fit does not (gcs_core.warmup)."""
    from gcs_core.warmup import warm_up

    _out("gcs warmup: compiling the numerical kernels once (about 30 s; the first fit then takes seconds)")
    seconds, left = warm_up(say=lambda text: _out(f"  {text}"))
    _out(
        f"gcs warmup: done in {seconds:.1f} s"
        + (f" ({len(left)} rarely used kernels compile on first use)" if left else "")
    )
    return EXIT_OK


def cmd_import(args, prog: Progress) -> int:
    from gcs_core.io.importer import load_mission
    from gcs_tui.cli.tables import import_table

    with prog.task(f"reading mission {args.mission}"):
        m = load_mission(args.mission)
    _lines(import_table(m))
    if args.sdf:
        from gcs_core.io.sdf_write import write_sdf

        with prog.task(f"writing the SDF {args.sdf}"):
            path = write_sdf(_output(args.sdf), m)
        _out(f"SDF written to {path}")
    _write_json(args.report, {"mission": m.spec.name, "command": "import", **m.report.to_dict()})
    return EXIT_OK


def cmd_convert(args, prog: Progress) -> int:
    from gcs_core.convert import convert

    options = {
        "overwrite": args.force,
        "tle": args.tle,
        "name": args.name,
        "span": tuple(args.span) if args.span else None,
    }
    with prog.task(f"converting {args.source} ({args.format})"):
        report = convert(args.format, args.source, args.out, **options)
    _lines(report.lines())
    return EXIT_OK


def cmd_noise(args, prog: Progress) -> int:
    from gcs_core.io.importer import load_mission
    from gcs_core.noise.measured import mission_noise, noise_lines

    with prog.task(f"reading mission {args.mission}"):
        m = load_mission(args.mission)
    with prog.task("Allan deviations"):
        res = mission_noise(m, start=args.start, end=args.end)
    _lines(noise_lines(res))
    return EXIT_OK


def cmd_batch(args, prog: Progress) -> int:
    from gcs_core.reporting import analysis_report
    from gcs_tui.cli.tables import candidate_table

    a = _analysis(args, prog)
    _fit(a, prog)
    if args.rank or args.report:  # ICD §7 reports always carry the candidates
        with prog.task("ranking candidate effects"):
            a.rank()
    _print_fit(a)
    if args.rank:
        _out("")
        _lines(candidate_table(a.candidates, alpha=a.config.diagnosis.significance))
    problem = ""
    if args.scds:
        from gcs_tui.cli.outputs import save_calibration_kept

        with prog.task(f"appending the calibration to {args.scds}"):
            v, where, problem = save_calibration_kept(a, _output(args.scds), args.note or "")
        _out(f"calibration saved as version {v} in {where}")
    _write_json(args.report, lambda: analysis_report(a, command="batch"))
    _write_noise_correlation(args, a)
    _export_plots(args, a)
    if problem:  # the fit is kept beside; the SCDS asked for did not take it
        return _error(prog, f"error: {args.scds}: {problem}; the calibration is saved in {where} instead", EXIT_INPUT)
    return EXIT_ESTIMATION if _fit_failed(a) else EXIT_OK


def cmd_discover(args, prog: Progress) -> int:

    from gcs_core.diagnosis.structure_text import report_lines
    from gcs_core.reporting import analysis_report, physics_why
    from gcs_tui.cli.tables import (
        candidate_table,
        remaining_lines,
        steps_table,
    )

    a = _analysis(args, prog)
    if args.significance is not None:
        a.config = a.config.with_changes(diagnosis={"significance": args.significance})
    a.search_sensors = tuple(args.search or ())
    _fit(a, prog)
    if _fit_failed(a):
        return EXIT_ESTIMATION
    with prog.task("discovering missing effects (score tests, refits)") as task:
        steps = a.discover(max_steps=args.max_steps, progress=step_messages(prog, task))
    added = [s.effect for s in steps if s.action == "add"]
    _print_fit(a)
    _out("")
    _out("effects added: " + (", ".join(added) if added else "none"))
    _lines("  " + line for line in steps_table(steps))
    _out("stopped: " + a.stop_reason)
    _lines("remaining: " + line for line in remaining_lines(a))
    structure = report_lines(a.structure_report, a.offered)
    if structure:
        _out("")
        _lines(structure)
    needed = a.physics_needed()
    if needed:
        _out("")
        _out("always-on physics in the model:")
        for d in needed:
            _out(f"  {d.id:<28} {'needed' if d.needed else 'not shown'}: {physics_why(d)}")
    if a.candidates:
        _out("")
        _lines(candidate_table(a.candidates, alpha=a.config.diagnosis.significance, limit=5))
    _write_json(args.report, lambda: analysis_report(a, command="discover"))
    _write_noise_correlation(args, a)
    _export_plots(args, a)
    if _fit_failed(a):
        return EXIT_ESTIMATION
    return EXIT_FLAG if (args.strict and added) else EXIT_OK


def cmd_effects(args, prog: Progress) -> int:
    from gcs_tui.cli.tables import effects_lines, generic_effects_lines

    width = max(60, min(120, _terminal_width()))
    if args.target:
        a = _analysis(args, prog)
        _lines(effects_lines(a.catalogue(), a.effects_in_state(), explain=args.explain, width=width))
        return EXIT_OK
    from gcs_core.diagnosis.catalogue import generic_catalogue

    _out("Effect ids are <SENSOR>.<effect> or model.<effect> (ICD §7); `gcs effects MISSION` lists a mission's.")
    _out("")
    _lines(generic_effects_lines(generic_catalogue(), width=width))
    return EXIT_OK


def cmd_predict(args, prog: Progress) -> int:
    """A plan (no mission directory) or a config with ``[trade.orbit]``: the plan as
    ``gcs trade`` reads it (:mod:`gcs_core.predictor.source`, no telemetry); otherwise the
    mission's telemetry span, cadences and onboard attitude."""
    from gcs_core.predictor.predict import predict
    from gcs_core.predictor.source import is_plan_file, load_source
    from gcs_tui.cli.tables import prediction_table

    cfg = _load(args)
    if is_plan_file(cfg) or (cfg.trade or {}).get("orbit"):
        with prog.task(f"reading the plan {cfg.path or cfg.mission}"):
            src = load_source(cfg)
        name = src.spec.name
        with prog.task("predicting the accuracy of the data plan (covariance only)"):
            res = src.predict()
    else:
        cfg, mission = _setup(args, prog)
        name = mission.spec.name
        with prog.task("predicting the accuracy of the data plan (covariance only)"):
            res = predict(cfg, mission=mission)
    for w in res.warnings:
        log.warning("%s", w)
    _lines(prediction_table(res))
    _write_json(args.report, {"mission": name, "command": "predict", **res.as_report()})
    return EXIT_OK


def cmd_verify(args, prog: Progress) -> int:
    from gcs_core.verif.analysis import verify_analysis

    a = _analysis(args, prog)
    _fit(a, prog, holdout=False)
    if _fit_failed(a):
        return EXIT_ESTIMATION
    with prog.task("comparing onboard and ground attitudes"):
        v = verify_analysis(a)
    _out(v.summary() if hasattr(v, "summary") else str(v))
    if args.asf:
        from gcs_core.calibration import save_ground_attitude

        with prog.task(f"appending the ground attitudes to {args.asf}"):
            n = save_ground_attitude(a, _output(args.asf))
        _out(f"ground attitudes saved as solution {n} in {args.asf}")
    _write_json(args.report, {"mission": a.mission.spec.name, "command": "verify", **v.as_report()})
    return EXIT_FLAG if v.flag else EXIT_OK


def _terminal_width() -> int:
    try:
        return os.get_terminal_size(sys.stdout.fileno()).columns
    except (OSError, ValueError, AttributeError):
        return 100


# ---------------------------------------------------------------------------- parser
class _Parser(argparse.ArgumentParser):
    """argparse with usage errors as one line (exit 2, like every bad input)."""

    def error(self, message: str):
        self.exit(EXIT_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


_positive_int = whole_number(1)


def _alpha(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 < v <= 0.5:
        raise argparse.ArgumentTypeError(f"must be in (0, 0.5], not {v}")
    return v


EPILOG = (
    "exit codes: 0 ok; 1 a finding to act on (verify flag, discover --strict added effects); "
    "2 bad input; 3 estimation failed; 4 internal error; 130 interrupted"
)


def _common(top: bool) -> _Parser:
    """The options every command takes, before or after its name (the command's copies
    default to SUPPRESS so they do not undo what was given before the name)."""
    common = _Parser(add_help=False)
    dflt = (lambda v: v) if top else (lambda v: argparse.SUPPRESS)
    common.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        default=dflt(False),
        help="debug logging (and the traceback of an internal error)",
    )
    common.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        default=dflt(False),
        help="no progress or log lines, only results, warnings and errors",
    )
    common.add_argument(
        "--progress",
        choices=MODES,
        default=dflt("auto"),
        help="progress display: a live line on a terminal (auto), always (bar), plain log lines (plain) or none (off)",
    )
    return common


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="gcs",
        description="GCS: calibrate and verify spacecraft attitude sensors",
        epilog=EPILOG,
        parents=[_common(True)],
    )
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_Parser)
    common = _common(False)

    def add(name: str, func, helptext: str):
        sp = sub.add_parser(name, help=helptext, description=helptext, parents=[common], epilog=EPILOG)
        sp.set_defaults(func=func)
        return sp

    def target(sp, required=True):
        sp.add_argument("target", nargs=None if required else "?", help="analysis config (.toml) or mission directory")

    sp = add("tui", cmd_tui, "the analyst's terminal UI")
    sp.add_argument(
        "target",
        nargs="?",
        default="sample_data/missions/hidden-tam-contamination",
        help="analysis config (.toml) or mission directory",
    )
    sp.add_argument(
        "--out",
        help="folder for the files the TUI writes unasked (config, SCDS, screenshots); "
        "default: beside the config, else beside the mission directory",
    )

    add("warmup", cmd_warmup, "compile the numerical kernels now (once per install; make run does it)")

    sp = add("import", cmd_import, "validate a mission directory, show what was read, write the SDF")
    sp.add_argument("mission", help="mission directory (ICD §1)")
    sp.add_argument("--sdf", help="write the Standard Data File (HDF5) here")
    sp.add_argument("--report", help="write the import counts (JSON) here")

    sp = add("convert", cmd_convert, "convert foreign data (astropi, broad) to a mission directory")
    sp.add_argument("format", help="the source format: astropi | broad")
    sp.add_argument("source", help="the file to convert")
    sp.add_argument("--out", required=True, help="the mission directory to write")
    sp.add_argument("--tle", help="two-line elements of the orbit (astropi)")
    sp.add_argument(
        "--span",
        nargs=2,
        type=float,
        metavar=("START", "END"),
        help="keep only the samples in this window [s from the first sample] (broad)",
    )
    sp.add_argument("--name", help="mission name (default from the source file)")
    sp.add_argument("--force", action="store_true", help="replace a non-empty output directory")

    sp = add("noise", cmd_noise, "each sensor's white noise and Allan deviation from its telemetry")
    sp.add_argument("mission", help="mission directory (ICD §1)")
    sp.add_argument("--start", type=float, help="first time used [s since the epoch]")
    sp.add_argument("--end", type=float, help="last time used [s since the epoch]")

    for name, func, helptext in (
        ("batch", cmd_batch, "fit the configured state"),
        ("discover", cmd_discover, "stepwise missing-effect discovery"),
    ):
        sp = add(name, func, helptext)
        target(sp)
        sp.add_argument("--report", help="write the JSON report (ICD §7) here")
        sp.add_argument("--method", choices=("whole_span", "batch", "kalman"), help="override the config's method")
        sp.add_argument(
            "--noise-weighting", choices=NOISE_WEIGHTINGS, help="override the config's [filter] noise_weighting"
        )
        sp.add_argument(
            "--sigma-window",
            type=seconds_or_zero,
            help="window [s] of the correlation-robust σ (default: 4, or 10 samples, fewer on short spans; 0 = off)",
        )
        sp.add_argument(
            "--write-noise-correlation",
            action="store_true",
            help="declare each sensor's significant measured noise correlation time in mission.toml",
        )
        sp.add_argument("--plots", help="export residual plots to this folder")
        sp.add_argument(
            "--plot-format",
            choices=("txt", "html"),
            default="txt",
            help="plain-text plots, one per component, or one HTML page",
        )
        if name == "batch":
            sp.add_argument("--rank", action="store_true", help="also print the ranked candidate effects")
            sp.add_argument("--scds", help="append the calibration to this SCDS (HDF5)")
            sp.add_argument("--note", help="note stored with the calibration")
        else:
            sp.add_argument("--max-steps", type=_positive_int, default=10, help="at most this many additions")
            sp.add_argument("--significance", type=_alpha, help="family-wise α (default from the config)")
            sp.add_argument("--strict", action="store_true", help="exit 1 when effects were added")
            sp.add_argument(
                "--search",
                action="append",
                metavar="SENSOR",
                help="also search this sensor's residual structure (repeatable; misfit sensors always are)",
            )

    sp = add("effects", cmd_effects, "list the catalogue of candidate effects")
    target(sp, required=False)
    sp.add_argument("--explain", action="store_true", help="with a TARGET: each effect's signature")

    sp = add("predict", cmd_predict, "covariance-only prediction for the data plan")
    target(sp)
    sp.add_argument("--report", help="write a JSON report here")

    sp = add("verify", cmd_verify, "onboard vs ground attitude, §4.4 flag")
    target(sp)
    sp.add_argument("--report", help="write a JSON report here")
    sp.add_argument("--asf", help="append the ground attitudes to this Attitude Status File")

    from gcs_tui.cli.trade import add_commands

    add_commands(add, target)
    from gcs_tui.cli.fleet import add_commands as add_fleet

    add_fleet(add, target)
    return p


# ---------------------------------------------------------------------------- main
def _install_logging(handler: logging.Handler, *, verbose: bool, quiet: bool) -> list:
    saved = []
    for name in LOGGERS:
        lg = logging.getLogger(name)
        saved.append((lg, lg.level))
        if verbose:
            lg.setLevel(logging.DEBUG)
        elif name == "gcs" and not quiet:
            lg.setLevel(logging.INFO)
        else:
            lg.setLevel(logging.WARNING)
        lg.addHandler(handler)
    return saved


def _restore_logging(handler: logging.Handler, saved: list) -> None:
    for lg, level in saved:
        lg.removeHandler(handler)
        lg.setLevel(level)


def _one_line(text: str) -> str:
    return " ".join(str(text).split("\n"))


def _error(prog: Progress, text: str, code: int) -> int:
    prog.close()
    sys.stderr.write(f"gcs: {terminal_safe(_one_line(text), one_line=True)}\n")
    return code


def _numeric_failure(err: BaseException) -> bool:
    """numpy's LinAlgError or a floating-point trap: the estimation failed, not GCS."""
    return type(err).__name__ == "LinAlgError" or isinstance(err, FloatingPointError)


def main(argv=None) -> int:
    """Run one ``gcs`` command; returns the exit code (module docstring)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2), already printed
        return exc.code if isinstance(exc.code, int) else EXIT_INPUT
    prog = Progress(sys.stderr, mode="off" if args.quiet else args.progress)
    handler = LogHandler(prog)
    saved = _install_logging(handler, verbose=args.verbose, quiet=args.quiet)
    saved_show = warnings.showwarning
    warnings.showwarning = warning_line  # no numpy source lines on stderr
    try:
        check_outputs(args)  # before any work: a bad output path costs no fitting time
        code = args.func(args, prog)
        sys.stdout.flush()
        if code != EXIT_INTERNAL:  # the TUI's crash line stays the only line
            prog.finish()
        return code
    except InputError as err:
        if err.file is None and err.key and getattr(args, "config_path", None) is not None:
            err.file = args.config_path  # a config key: name the config it is in
        kind = "config error" if isinstance(err, ConfigError) else "error"
        return _error(prog, f"{kind}: {err}", EXIT_INPUT)
    except EstimationError as err:
        return _error(prog, f"estimation failed: {err}", EXIT_ESTIMATION)
    except GcsError as err:
        return _error(prog, f"error: {err}", EXIT_INPUT)
    except KeyboardInterrupt:
        return _error(prog, "interrupted", EXIT_INTERRUPT)
    except BrokenPipeError:  # stdout closed early (gcs ... | head): not an error
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        return EXIT_OK
    except Exception as err:  # noqa: BLE001 — the last line of defence: one line, no traceback
        if _numeric_failure(err):
            return _error(prog, f"estimation failed: {type(err).__name__}: {err}", EXIT_ESTIMATION)
        if args.verbose:
            prog.close()
            traceback.print_exc(file=sys.stderr)
        return _error(
            prog,
            f"internal error: {type(err).__name__}: {err} — a bug in GCS; please report it "
            "(rerun with -v for the traceback)",
            EXIT_INTERNAL,
        )
    finally:
        prog.close()
        warnings.showwarning = saved_show
        _restore_logging(handler, saved)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
