"""``gcs fleet MANIFEST`` — a fleet's daily calibration on Dask (:mod:`gcs_core.fleet`,
docs/fleet.md); ``gcs fleet-sim OUT`` — a simulated fleet to try it on.

``gcs fleet`` prints one progress line per spacecraft-day as its result is appended, then
the fleet table; it writes the JSON report and the HTML page (default: in the manifest's
output folder) and, with ``--aem DIR``, each computed day's attitude as a CCSDS AEM.
Exit codes: 0 nothing to act on; 1 a spacecraft-day failed, raised the §4.4 flag, was
not consistent with noise, moved a parameter or discovered an effect; 2 bad manifest.
"""

from __future__ import annotations

import sys
from pathlib import Path

from gcs_tui.cli.arguments import whole_number

_count = whole_number(1)


def _out(text: str = "") -> None:
    sys.stdout.write(text + "\n")


def _table(report: dict) -> list[str]:
    lines = [f"{'spacecraft':<12} {'day':<12} {'state':<13} {'fit':<22} {'§4.4':<6} moved / discovered / error"]
    for sc in report["spacecraft"]:
        for r in sc["days"]:
            if r.get("error"):
                fit, flag, rest = "", "", r["error"]
            else:
                fit = "consistent with noise" if r.get("adequate") else "model inadequate"
                flag = {True: "FLAG", False: "ok", None: "-"}[r.get("flag")]
                moved = ", ".join(m["element"] for m in r.get("moved", []))
                rest = "; ".join(x for x in (moved and f"moved {moved}", ", ".join(r.get("discovered", []))) if x)
            lines.append(f"{sc['name']:<12} {r['day']:<12} {r['state']:<13} {fit:<22} {flag:<6} {rest}")
    return lines


def _act_on(report: dict) -> bool:
    rows = [r for sc in report["spacecraft"] for r in sc["days"]]
    return any(
        r.get("error") or r.get("flag") or r.get("adequate") is False or r.get("moved") or r.get("discovered")
        for r in rows
    )


def _export_aem(m, run, out: Path) -> int:
    from gcs_core.fleet.ccsds import write_aem
    from gcs_core.fleet.store import FleetStore
    from gcs_core.io import asf
    from gcs_core.io.mission import read_mission_spec

    store, n = FleetStore(m.output), 0
    for e in run.entries:
        if e.asf_solution is None:
            continue
        sol = asf.read_solution(store.asf_path(e.spacecraft), e.asf_solution)
        spec = read_mission_spec(m.mission_dir(m.spacecraft_named(e.spacecraft), e.day))
        comments = (
            f"GCS ASF solution {e.asf_solution}, SCDS version {e.scds_version}",
            f"input hash {e.input_hash}",
        )
        write_aem(
            out / f"{e.spacecraft}-{e.day}.aem.xml",
            sol.t,
            sol.q,
            spec.epoch,
            object_name=e.spacecraft,
            comments=comments,
        )
        n += 1
    return n


def cmd_fleet(args, prog) -> int:
    from gcs_core.fileperm import write_atomic
    from gcs_core.fleet.html import render_html
    from gcs_core.fleet.manifest import read_manifest
    from gcs_core.fleet.report import build_report
    from gcs_core.fleet.run import run_fleet
    from gcs_core.reporting import write_json_atomic

    args.config_path = args.manifest
    m = read_manifest(args.manifest)
    for d in args.day or []:
        if d not in m.days:
            from gcs_core.errors import ConfigError

            raise ConfigError(
                f"--day {d} is not one of the manifest's days ({', '.join(m.days)})", key="fleet.days", file=m.path
            )
    for s in args.spacecraft or []:
        try:
            m.spacecraft_named(s)
        except KeyError:
            from gcs_core.errors import ConfigError

            raise ConfigError(f"--spacecraft {s} is not in the manifest", key="spacecraft", file=m.path) from None

    def progress(entry, text: str) -> None:
        prog.message(f"{entry.spacecraft} {entry.day}: {text}")

    run = run_fleet(
        m, days=args.day, spacecraft=args.spacecraft, workers=args.workers, scheduler=args.scheduler, progress=progress
    )
    report = build_report(m, run, days=args.day)
    _out("\n".join(_table(report)))
    json_path = Path(args.report) if args.report else m.output / "fleet-report.json"
    html_path = Path(args.html) if args.html else m.output / "fleet-report.html"
    write_json_atomic(json_path, report)
    write_atomic(html_path, render_html(report), parents=True)
    _out(f"report: {json_path} and {html_path}")
    if args.aem:
        _out(f"{_export_aem(m, run, Path(args.aem))} AEM file(s) written to {args.aem}")
    return 1 if _act_on(report) else 0


def cmd_fleet_sim(args, prog) -> int:
    from gcs_core.fleet.simulate import simulate_fleet

    with prog.task(f"simulating {args.spacecraft} spacecraft × {args.days} days"):
        path = simulate_fleet(args.out, args.spacecraft, args.days, duration_s=args.span, seed=args.seed)
    _out(f"fleet manifest: {path} (answers in {path.parent / 'truth.json'})")
    return 0


def add_commands(add, target) -> None:
    """Register ``gcs fleet`` and ``gcs fleet-sim`` (``add``/``target`` from commands.py)."""
    sp = add("fleet", cmd_fleet, "a fleet's daily calibration, discovery and verification on Dask")
    sp.add_argument("manifest", help="the fleet manifest (TOML, docs/fleet.md)")
    sp.add_argument("--day", action="append", help="run only this day (repeatable; default: every day)")
    sp.add_argument("--spacecraft", action="append", help="run only this spacecraft (repeatable)")
    sp.add_argument("--workers", type=_count, default=2, help="local worker processes (default 2)")
    sp.add_argument("--scheduler", help="address of a running Dask scheduler (tcp://host:port) instead")
    sp.add_argument("--report", help="the JSON report (default: <output>/fleet-report.json)")
    sp.add_argument("--html", help="the HTML page (default: <output>/fleet-report.html)")
    sp.add_argument("--aem", help="write each computed day's attitude as a CCSDS AEM (XML) in this folder")

    sp = add("fleet-sim", cmd_fleet_sim, "write a simulated fleet (missions, manifest, answers)")
    sp.add_argument("out", help="the folder to write")
    sp.add_argument("--spacecraft", type=_count, default=4, help="how many spacecraft (default 4)")
    sp.add_argument("--days", type=_count, default=2, help="how many consecutive days (default 2)")
    sp.add_argument("--span", type=float, default=1200.0, help="seconds of data per day (default 1200)")
    sp.add_argument("--seed", type=int, default=1, help="the simulation's seed")
