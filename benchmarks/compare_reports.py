"""Compare two trees of JSON reports (ICD §7): every number within a relative tolerance.

A refactoring of the engine must leave every report as it was. Run the same commands before
and after into two folders, then::

    python benchmarks/compare_reports.py BEFORE_DIR AFTER_DIR [--rtol 1e-9] [--ignore /sigma_scale/]

Each ``*.json`` of BEFORE is read with its namesake in AFTER and walked together: objects
must have the same keys, lists the same length, strings and booleans be equal, and numbers
agree within ``rtol`` relative (``|a − b| ≤ rtol · max(|a|, |b|)``; exact for zero). Prints
one line per difference (path in the report, before, after) and a summary; exit 1 when any
report differs or is missing, 0 when all agree.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any


def _numbers_agree(a: float, b: float, rtol: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= rtol * max(abs(a), abs(b))


def differences(before: Any, after: Any, rtol: float, path: str = "") -> list[str]:
    """Each place where two decoded JSON values differ, as ``path: before != after``."""
    is_num = (int, float)
    if isinstance(before, bool) or isinstance(after, bool):
        return [] if before is after else [f"{path}: {before!r} != {after!r}"]
    if isinstance(before, is_num) and isinstance(after, is_num):
        return [] if _numbers_agree(float(before), float(after), rtol) else [f"{path}: {before!r} != {after!r}"]
    if isinstance(before, dict) and isinstance(after, dict):
        out = [f"{path}/{k}: only before" for k in before if k not in after]
        out += [f"{path}/{k}: only after" for k in after if k not in before]
        for k in before:
            if k in after:
                out += differences(before[k], after[k], rtol, f"{path}/{k}")
        return out
    if isinstance(before, list) and isinstance(after, list):
        if len(before) != len(after):
            return [f"{path}: length {len(before)} != {len(after)}"]
        out = []
        for i, (x, y) in enumerate(zip(before, after, strict=True)):
            out += differences(x, y, rtol, f"{path}[{i}]")
        return out
    return [] if before == after else [f"{path}: {before!r} != {after!r}"]


def compare_trees(
    before_dir: Path, after_dir: Path, rtol: float, ignore: tuple[str, ...] = ()
) -> tuple[int, int, list[str]]:
    """(reports compared, reports differing, difference lines) over BEFORE's ``*.json``;
    differences under a path starting with one of ``ignore`` (``/sigma_scale/``) left out."""
    lines: list[str] = []
    compared = differing = 0
    for before_path in sorted(before_dir.rglob("*.json")):
        rel = before_path.relative_to(before_dir)
        after_path = after_dir / rel
        compared += 1
        if not after_path.exists():
            differing += 1
            lines.append(f"{rel}: missing after")
            continue
        diffs = differences(json.loads(before_path.read_text()), json.loads(after_path.read_text()), rtol)
        diffs = [d for d in diffs if not d.startswith(ignore)] if ignore else diffs
        if diffs:
            differing += 1
            lines += [f"{rel} {d}" for d in diffs]
    return compared, differing, lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--rtol", type=float, default=1e-9, help="relative tolerance on numbers")
    parser.add_argument(
        "--ignore",
        action="append",
        default=[],
        metavar="PATH",
        help="leave out differences under this report path (e.g. /sigma_scale/ after a change of that statistic)",
    )
    args = parser.parse_args(argv)
    compared, differing, lines = compare_trees(args.before, args.after, args.rtol, tuple(args.ignore))
    for line in lines:
        print(line)
    left_out = f"; left out: {', '.join(args.ignore)}" if args.ignore else ""
    print(f"{compared} reports compared, {differing} differ (rtol {args.rtol:g}{left_out})")
    return 1 if differing or compared == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
