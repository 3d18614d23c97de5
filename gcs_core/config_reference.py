"""The analysis config's key reference, generated from the config's dataclass fields.

Every key of :mod:`gcs_core.config` carries its meaning, unit and bounds in its field's
metadata (``_doc``); :func:`render` turns them into ``docs/reference/config.md``, and
``tests/unit/test_config_reference.py`` fails when a key has no documentation, when a
documented bound is not enforced, or when the committed file is stale. Regenerate with::

    python -m gcs_core.config_reference            # writes docs/reference/config.md

The planning tables (``[trade]``, ``[montecarlo]``) are free tables read by
:mod:`gcs_core.trade`; their keys are documented in :data:`PLANNING_DOCS` here.
"""

from __future__ import annotations

import sys
from dataclasses import MISSING, Field, fields, is_dataclass
from pathlib import Path
from typing import Any

from gcs_core.config_schema import ANALYSIS_KEYS, AnalysisConfig, ElementConfig, Maneuver
from gcs_core.fileperm import write_atomic

#: where :func:`main` writes the reference, relative to the repository root
REFERENCE = Path("docs") / "reference" / "config.md"
COMMAND = "python -m gcs_core.config_reference"

#: the planning tables' keys (checked in detail by :mod:`gcs_core.trade`, with its examples)
PLANNING_DOCS: dict[str, dict[str, str]] = {
    "trade": {
        "vary": "table: a plan key (gcs_core/trade/space.py) -> the list of its values",
        "targets": "elements, effect ids, `NAME.misalignment` or `attitude` the plans are ranked by",
        "orbit": "table of Kepler elements (a_km, e, i_deg, raan_deg, argp_deg, mean_anomaly_deg) for every plan",
        "top": "error budgets printed for the best plans (default 3)",
        "output": "results file (HDF5), relative to the config",
        "optimize": "`gcs optimize`: `targets` (`ELEMENT<SIGMA[unit]`) and `budget` (slew_min, hours, axes, rates)",
    },
    "montecarlo": {
        "runs": "number of simulated fits (default 100)",
        "seed": "entropy of the runs' SeedSequence (default 20261202)",
        "output": "results file (HDF5), relative to the config",
    },
}

_TYPES = {
    "float": "number",
    "float | None": "number",
    "int": "integer",
    "bool": "true/false",
    "str": "string",
    "str | None": "string",
    "Path": "path",
    "Path | None": "path",
    "tuple[str, ...]": "list of strings",
    "tuple[tuple[float, float], ...]": "list of [start, end]",
    "tuple[Maneuver, ...]": "array of tables",
    "dict[str, float]": "table",
    "dict[str, str]": "table",
    "dict[str, ElementConfig]": "table of tables",
}


def key_fields() -> list[tuple[str, Field]]:
    """``(dotted key, field)`` for every key of a config, in the order of the dataclasses:
    ``[analysis]``'s, each table's, then the sub-tables (an element's override, a maneuver)."""
    out: list[tuple[str, Field]] = []
    top = {f.name: f for f in fields(AnalysisConfig)}
    out += [(f"analysis.{k}", top[k]) for k in ANALYSIS_KEYS]
    for f in fields(AnalysisConfig):
        if f.name in ("path", *ANALYSIS_KEYS):
            continue
        out.append((f.name, f))
        if is_dataclass(f.default_factory):
            out += [(f"{f.name}.{g.name}", g) for g in fields(f.default_factory)]
    out += [(f'state.elements."NAME".{g.name}', g) for g in fields(ElementConfig)]
    out += [(f"prediction.maneuvers[i].{g.name}", g) for g in fields(Maneuver)]
    return out


def undocumented(entries: list[tuple[str, Field]] | None = None) -> list[str]:
    """The keys whose field carries no ``doc`` metadata (none, once every key is documented)."""
    return [k for k, f in (entries if entries is not None else key_fields()) if not f.metadata.get("doc")]


def _default(f: Field) -> str:
    if f.metadata.get("required"):
        return "required"
    if f.default is not MISSING:
        v = f.default
    elif f.default_factory is not MISSING:
        v = f.default_factory()
        if is_dataclass(v):
            return "(table)"
    else:
        return "required"
    if v is None or v == () or v == {}:
        return "—"
    if isinstance(v, bool):
        return f"`{str(v).lower()}`"
    if isinstance(v, str):
        return f'`"{v}"`'
    return f"`{v}`"


def bounds(meta: Any) -> str:
    """The bounds of a key as text (``> 0``, ``[1, 1000]``, ``one of …``)."""
    parts = []
    if meta.get("choices"):
        parts.append("one of " + ", ".join(f"`{c}`" for c in meta["choices"]))
    lo, hi = meta.get("lo"), meta.get("hi")
    if meta.get("positive"):
        parts.append("> 0" if hi is None else f"(0, {hi:g}]")
    elif lo is not None and hi is not None:
        parts.append(f"[{lo:g}, {hi:g}]")
    elif lo is not None:
        parts.append(f"≥ {lo:g}")
    elif hi is not None:
        parts.append(f"≤ {hi:g}")
    if meta.get("integer"):
        parts.append("whole")
    return "; ".join(parts) or "—"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def render() -> str:
    """The Markdown reference of every config key (``docs/reference/config.md``)."""
    lines = [
        "# Analysis config: every key",
        "",
        f"Generated from the fields of `gcs_core/config_schema.py` by `{COMMAND}`; do not edit by hand",
        "(`tests/unit/test_config_reference.py` fails when it is stale, when a key has no",
        "documentation, or when a bound listed here is not enforced). An annotated example is the",
        "docstring of `gcs_core/config.py`; `sample_data/configs/` holds one config per sample",
        "mission. Units are those of the key's name; an element's `value` and `sigma` are in the",
        "element's internal unit (`gcs effects TARGET --explain` lists them).",
        "",
    ]
    current = None
    for key, f in key_fields():
        table = "analysis" if key.startswith("analysis.") else key.rsplit(".", 1)[0] if "." in key else None
        if table is None:  # a table of its own: its heading and what it is
            current = key
            lines += ["", f"## [{key}]", "", _cell(str(f.metadata.get("doc", ""))), ""]
            if key in PLANNING_DOCS:
                lines += ["| key | meaning |", "|---|---|"]
                lines += [f"| `{key}.{k}` | {_cell(d)} |" for k, d in PLANNING_DOCS[key].items()]
            continue
        if table != current:
            current = table
            heading = "## [analysis]" if table == "analysis" else f"### {table}"
            lines += ["", heading, ""]
        if lines[-1] == "" and not lines[-2].startswith("|"):
            lines += ["| key | type | default | unit | bounds | meaning |", "|---|---|---|---|---|---|"]
        m = f.metadata
        kind = _TYPES.get(str(f.type), str(f.type))
        lines.append(
            f"| `{key}` | {kind} | {_default(f)} | {_cell(m.get('unit') or '—')} | {_cell(bounds(m))} "
            f"| {_cell(str(m.get('doc', '')))} |"
        )
    text = "\n".join(lines).replace("\n\n\n", "\n\n")
    return text.strip() + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write the reference to ``argv[0]`` (default ``docs/reference/config.md``)."""
    args = sys.argv[1:] if argv is None else argv
    write_atomic(Path(args[0]) if args else REFERENCE, render(), parents=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
