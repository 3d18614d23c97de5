"""Code downstream of the estimators never asks which estimator ran (issue 21).

The session, the diagnosis, VERIF, the reports and the faces read a fit through the result
protocol (:class:`gcs_core.estimators.results.FitResult`) and the registry
(:mod:`gcs_core.estimators.registry`). Checked on the source with ``ast`` (nothing is
imported): outside the registry and the config reader there is no ``getattr(…, "dynamics"…)``,
no comparison of a method name with ``"batch"``, ``"whole_span"`` or ``"kalman"``, and no
``isinstance`` on a result type. :data:`PENDING` lists the places still to be moved (each in
the area that owns it); it may only shrink.
"""

from __future__ import annotations

import ast

from repo_paths import ROOT

from gcs_core.config_schema import METHODS
from gcs_core.estimators.registry import ESTIMATORS

#: where the method's name may be read: the registry and the config reader
ALLOWED = {"gcs_core/estimators/registry.py", "gcs_core/config.py", "gcs_core/config_checks.py"}
#: result types no downstream code may test for
RESULT_TYPES = {"BatchResult", "SmoothedResult", "FilterResult", "FitResult"}
#: module -> offences still there (each to be moved by the area that owns it; may only shrink)
PENDING: dict[str, int] = {}


def _offences(tree: ast.AST) -> list[str]:
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            args = node.args
            if node.func.id == "getattr" and len(args) >= 2 and isinstance(args[1], ast.Constant):
                if args[1].value == "dynamics":
                    out.append(f"line {node.lineno}: getattr(…, 'dynamics')")
            if node.func.id == "isinstance" and len(args) == 2:
                kinds = args[1].elts if isinstance(args[1], ast.Tuple) else [args[1]]
                if any(isinstance(k, ast.Name) and k.id in RESULT_TYPES for k in kinds):
                    out.append(f"line {node.lineno}: isinstance on a result type")
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(isinstance(s, ast.Constant) and s.value in METHODS for s in sides) and any(
                (isinstance(s, ast.Name) and s.id == "method") or (isinstance(s, ast.Attribute) and s.attr == "method")
                for s in sides
            ):
                out.append(f"line {node.lineno}: a branch on the method's name")
    return out


def offences() -> dict[str, list[str]]:
    found = {}
    for pkg in ("gcs_core", "gcs_tui"):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = str(path.relative_to(ROOT))
            if rel in ALLOWED:
                continue
            hits = _offences(ast.parse(path.read_text(encoding="utf-8")))
            if hits:
                found[rel] = hits
    return found


def test_downstream_code_never_asks_which_estimator_ran():
    found = offences()
    new = {k: v for k, v in found.items() if k not in PENDING}
    assert new == {}
    grown = {k: v for k, v in found.items() if k in PENDING and len(v) > PENDING[k]}
    assert grown == {}


def test_the_pending_list_only_shrinks():
    found = offences()
    assert {k: n for k, n in PENDING.items() if len(found.get(k, [])) < n} == {}


def test_every_configurable_method_has_an_estimator():
    assert set(ESTIMATORS) == set(METHODS)
    for name, est in ESTIMATORS.items():
        assert est.name == name and est.training in ESTIMATORS
