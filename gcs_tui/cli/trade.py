"""``gcs trade``, ``gcs optimize`` and ``gcs montecarlo``: plan before launch (seed §1.1).

* ``gcs trade CONFIG --vary KEY=VALUES ...`` — the predictor over every combination; a
  ranked table of the targets' σ, the error budget of the best plans, the HDF5 results
  (``--output``, resumable with ``--resume``) and a plot (``--plot``);
* ``gcs optimize CONFIG --target 'TAM1.alignment<0.01deg' ...`` — the cheapest plan
  meeting the targets within the budget, and why it works;
* ``gcs montecarlo CONFIG --runs N`` — simulate and fit the plan N times; scatter
  against the predicted σ.

``--workers N`` runs on a local Dask cluster of N processes, ``--scheduler ADDRESS`` on an
existing one; serial otherwise. Ctrl-C keeps every finished plan (run) in the file.
"""

from __future__ import annotations

import sys
from pathlib import Path

from gcs_core import limits
from gcs_core.errors import InputError
from gcs_core.textsafe import terminal_safe
from gcs_tui.cli.arguments import whole_number

EXIT_OK, EXIT_FLAG, EXIT_INPUT, EXIT_INTERRUPT = 0, 1, 2, 130
#: the estimators a plan can be predicted for (gcs_core.config_schema.METHODS, the default first)
METHODS = ("whole_span", "batch", "kalman")


def _out(text: str = "") -> None:
    sys.stdout.write(terminal_safe(text) + "\n")


def _engine_options(args) -> dict:
    """The execution options ``run_study`` and ``run_montecarlo`` both take, from the
    command line (workers, scheduler, resume, overwrite, batch)."""
    return {
        "workers": args.workers or None,
        "scheduler": args.scheduler,
        "resume": args.resume,
        "overwrite": args.overwrite,
        "batch": args.batch,
    }


def _progress(task, what: str):
    """A (done, total) callback: the bar every time, a plain line every 10 %."""
    state = {"tenth": -1}

    def cb(done: int, total: int) -> None:
        tenth = int(10 * done / total) if total else 10
        text = ""
        if tenth != state["tenth"]:
            state["tenth"] = tenth
            text = f"{done}/{total} {what}"
        task(done, total, text)

    return cb


def _count(text: str) -> int:
    return whole_number(0)(text)


def _scale_args(sp) -> None:
    sp.add_argument("--workers", type=_count, default=0, help="run on a local Dask cluster of N processes")
    sp.add_argument("--scheduler", help="run on an existing Dask cluster (tcp://host:port)")
    sp.add_argument(
        "--batch", type=_count, help="plans (runs) per Dask task (default: about 4 tasks per worker; Monte Carlo: 1)"
    )
    sp.add_argument("--resume", action="store_true", help="compute only what the output file lacks")
    sp.add_argument("--overwrite", action="store_true", help="replace an existing output file")


def add_commands(add, target) -> None:
    """Register the three commands on the ``gcs`` parser (``add``/``target`` from cli.py)."""
    sp = add("trade", cmd_trade, "trade study: the predictor over many plans and configurations")
    target(sp)
    sp.add_argument(
        "--vary",
        action="append",
        default=[],
        metavar="KEY=VALUES",
        help="a key and its values (V1,V2,... or FIRST:LAST:STEP); repeat for more keys",
    )
    sp.add_argument(
        "--target",
        dest="target_",
        action="append",
        default=[],
        metavar="ELEMENT",
        help="element, effect id or 'attitude' whose σ ranks the plans (repeatable)",
    )
    sp.add_argument("--output", help="HDF5 results file (default: [trade] output)")
    sp.add_argument("--plot", help="write the plot of σ against the varied keys here (text)")
    sp.add_argument("--top", type=_count, help="error budgets of this many best plans")
    sp.add_argument("--limit", type=_count, default=20, help="rows of the table")
    sp.add_argument("--method", choices=METHODS, help="override the config's method (default whole_span)")
    _scale_args(sp)

    sp = add("optimize", cmd_optimize, "the cheapest data plan meeting σ targets within a budget")
    target(sp)
    sp.add_argument(
        "--target",
        dest="target_",
        action="append",
        default=[],
        metavar="ELEMENT<SIGMA",
        help="e.g. 'TAM1.alignment<0.01deg', 'FHST1.align_1<10arcsec' (repeatable)",
    )
    sp.add_argument("--slew-min", type=float, help="budget: most minutes of slewing")
    sp.add_argument("--hours", type=float, help="budget: most hours of data")
    sp.add_argument("--axes", help="allowed maneuver axes, e.g. roll,yaw")
    sp.add_argument("--rates", help="allowed maneuver rates [deg/s], e.g. 0.05,0.1")
    sp.add_argument("--starts", help="start phases the operator can choose [min from the plan start], e.g. 0,30,60")
    sp.add_argument("--passes", help="numbers of passes the data may be split into, e.g. 1,2")
    sp.add_argument("--windows", help="sensors' most minutes of data, placed by the search, e.g. FHST2=10")
    sp.add_argument("--write-config", help="write the chosen plan as an analysis config here")
    sp.add_argument("--method", choices=METHODS, help="override the config's method (default whole_span)")
    sp.add_argument("--workers", type=_count, default=0, help="run on a local Dask cluster of N processes")
    sp.add_argument("--scheduler", help="run on an existing Dask cluster")

    sp = add("montecarlo", cmd_montecarlo, "simulate and fit the plan N times: scatter against predicted σ")
    target(sp)
    sp.add_argument("--runs", type=_count, help="number of runs (default: [montecarlo] runs, else 100)")
    sp.add_argument("--seed", type=int, help="entropy of the SeedSequence (default: [montecarlo] seed)")
    sp.add_argument("--output", help="HDF5 results file (default: [montecarlo] output)")
    sp.add_argument("--plot", help="write the plot of scatter / predicted σ here (text)")
    sp.add_argument("--replay", type=int, metavar="RUN", help="re-run one run of the output file and compare")
    _scale_args(sp)


# ---------------------------------------------------------------------------- trade
def cmd_trade(args, prog) -> int:
    from gcs_core.config import load_config
    from gcs_core.trade.report import budget_lines, study_table
    from gcs_core.trade.run import run_study
    from gcs_core.trade.space import parse_vary
    from gcs_core.trade.study import definition_from_config

    cfg = load_config(args.target)
    assert cfg.path is not None  # a loaded config keeps its file's path
    args.config_path = cfg.path
    defn = definition_from_config(cfg, parse_vary(args.vary), args.target_ or None, method=args.method, top=args.top)
    output = args.output or cfg.trade.get("output")
    if output is not None:
        output = Path(output) if Path(output).is_absolute() or args.output else Path(cfg.path).parent / output
    n = len(defn.combos())
    try:
        with prog.task(
            f"trade study: {n} plans"
            + (f" on {args.workers} workers" if args.workers else "")
            + (f" on {args.scheduler}" if args.scheduler else ""),
            total=n,
        ) as task:
            rows = run_study(
                defn,
                output,
                **_engine_options(args),
                progress=_progress(task, "plans"),
            )
    except KeyboardInterrupt:
        if output is not None and Path(output).exists():
            from gcs_core.trade.run import read_study

            _, kept = read_study(output)
            sys.stderr.write(
                f"gcs: interrupted: {len(kept)} of {n} plans are in {output}; rerun with --resume for the rest\n"
            )
        raise
    for line in study_table(rows, limit=args.limit):
        _out(line)
    _out("")
    _out("error budget of the best plans (σ = noise ⊕ consider elements):")
    for line in budget_lines(rows, defn.top):
        _out(line)
    warned = [r for r in rows if r.warnings]
    if warned:  # one line for the study: the first plan's numbers and how many plans warn
        sys.stderr.write(
            f"gcs: warning: {len(warned)} of {len(rows)} plans, e.g. {warned[0].plan_id}: {warned[0].warnings[0]}\n"
        )
    if output is not None:
        _out(f"\n{len(rows)} plans in {output}")
    if args.plot:
        from gcs_tui.cli.trade_plot import study_plot

        path = Path(args.plot)
        from gcs_core.trade.run import varied_keys

        _write(path, study_plot(rows, varied_keys([r for r in rows if r.status == "ok"]) or tuple(defn.vary)))
        _out(f"plot written to {path}")
    if rows and all(r.status != "ok" for r in rows):
        sys.stderr.write(f"gcs: error: no plan of the study could be predicted, e.g. {rows[0].status}\n")
        return EXIT_INPUT
    return EXIT_OK


def _write(path: Path, text: str) -> None:
    from gcs_core.fileperm import write_atomic

    if not path.parent.is_dir():
        raise InputError("directory does not exist", file=path.parent)
    write_atomic(path, text)


# ---------------------------------------------------------------------------- optimize
def cmd_optimize(args, prog) -> int:
    from gcs_core.config import load_config, save_config
    from gcs_core.trade.optimize import Budget, optimize, parse_target

    cfg = load_config(args.target)
    args.config_path = cfg.path
    opt = dict(cfg.trade.get("optimize", {}))
    targets = [parse_target(t) for t in (args.target_ or opt.get("targets", []))]
    if not targets:
        raise InputError("give at least one --target ELEMENT<SIGMA", key="trade.optimize.targets")
    budget = Budget.from_mapping(
        opt.get("budget", {}),
        slew_min=args.slew_min,
        hours=args.hours,
        axes=args.axes,
        rates=args.rates,
        starts=args.starts,
        passes=args.passes,
        windows=args.windows,
    )
    with prog.task("searching the plan space", total=None) as task:
        res = optimize(
            cfg,
            targets,
            budget,
            method=args.method,
            workers=args.workers or None,
            scheduler=args.scheduler,
            progress=_progress(task, "plans"),
        )
    for line in res.lines():
        _out(line)
    if res.best is not None and res.config is not None and args.write_config:
        path = save_config(res.config, Path(args.write_config))
        _out(f"plan written to {path} (gcs montecarlo {path} checks it)")
        if res.best.description.get("sensor_gaps"):
            _out("note: the sensors' own windows are not in a config; give them as [[sensor]] gaps of a plan file")
    return EXIT_OK if res.best is not None else EXIT_FLAG


# ---------------------------------------------------------------------------- Monte Carlo
def cmd_montecarlo(args, prog) -> int:
    from gcs_core.config import load_config
    from gcs_core.trade.montecarlo import MonteCarlo, replay, run_montecarlo, summary_lines

    cfg = load_config(args.target)
    assert cfg.path is not None  # a loaded config keeps its file's path
    args.config_path = cfg.path
    mc = cfg.montecarlo
    runs = args.runs if args.runs is not None else mc.get("runs", 100)
    if isinstance(runs, bool) or not isinstance(runs, int) or not 1 <= runs <= limits.MAX_MONTECARLO_RUNS:
        key = "--runs" if args.runs is not None else "montecarlo.runs"
        raise InputError(f"must be a whole number from 1 to {limits.MAX_MONTECARLO_RUNS}, not {runs!r}", key=key)
    seed = args.seed if args.seed is not None else int(mc.get("seed", 20261202))
    output = args.output or mc.get("output")
    if output is not None and not args.output and not Path(output).is_absolute():
        output = Path(cfg.path).parent / output
    spec = MonteCarlo(str(Path(cfg.path).resolve()), runs, seed)
    if args.replay is not None:
        if output is None:
            raise InputError("--replay needs the results file (--output)", key="montecarlo.output")
        with prog.task(f"replaying run {args.replay}"):
            lines = replay(output, args.replay)
        for line in lines:
            _out(line)
        return EXIT_OK
    try:
        with prog.task(
            f"Monte Carlo: {runs} runs" + (f" on {args.workers} workers" if args.workers else ""), total=runs
        ) as task:
            result = run_montecarlo(
                spec,
                output,
                **_engine_options(args),
                progress=_progress(task, "runs"),
            )
    except KeyboardInterrupt:
        if output is not None:
            sys.stderr.write(f"gcs: interrupted: finished runs are in {output}; rerun with --resume\n")
        raise
    for line in summary_lines(result):
        _out(line)
    if args.plot:
        from gcs_tui.cli.trade_plot import montecarlo_plot

        _write(Path(args.plot), montecarlo_plot(result))
        _out(f"plot written to {args.plot}")
    return EXIT_OK if result.consistent else EXIT_FLAG


__all__ = ["add_commands", "cmd_montecarlo", "cmd_optimize", "cmd_trade"]
