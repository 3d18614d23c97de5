"""The folder tree shows the data's way, and the imports keep to it.

mission files (io) → problem (state, geometry, attitude) → noise → estimators (then the
predictor) → diagnosis → reports and the session → the faces (gcs_tui). Every module's
imports, at any depth of the file (function-level imports included), are read with
``ast``; nothing is imported, so the test is fast and sees imports that never run.
Imports under ``if TYPE_CHECKING:`` are left out: they are annotations for the type
checker (a screen's ``app`` is the running ``GcsApp``), never executed, so they order
nothing at run time.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("gcs_core", "gcs_tui")

#: layers from the bottom; a module may import its own layer (without cycles) and those below
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    (
        "foundation",
        (
            "gcs_core",
            "gcs_core.errors",
            "gcs_core.cancel",
            "gcs_core.inputs",
            "gcs_core.units",
            "gcs_core.fileperm",
            "gcs_core.compiled",
            "gcs_core.toml_values",
            "gcs_core.json_values",
            "gcs_core.display",
            "gcs_core.linalg",
            "gcs_core.frames",
            "gcs_core.ephem",
            "gcs_core.sim",
        ),
    ),
    ("mission files", ("gcs_core.io",)),
    ("models", ("gcs_core.models",)),
    ("problem", ("gcs_core.problem",)),
    (
        "analysis config",
        (
            "gcs_core.config_schema",
            "gcs_core.config",
            "gcs_core.config_checks",
            "gcs_core.config_problem",
            "gcs_core.config_reference",
        ),
    ),
    ("noise characterisation", ("gcs_core.noise",)),
    ("estimators", ("gcs_core.estimators",)),
    ("predictor", ("gcs_core.predictor",)),
    ("diagnosis", ("gcs_core.diagnosis",)),
    (
        "reports and session",
        (
            "gcs_core.verif",
            "gcs_core.calibration",
            "gcs_core.reporting",
            "gcs_core.session",
            "gcs_core.stepwise",
            "gcs_core.warmup",
            "gcs_core.trade",
            "gcs_core.convert",
        ),
    ),
    ("fleet", ("gcs_core.fleet",)),  # many spacecraft over the session's engine (docs/fleet.md)
    ("faces", ("gcs_tui",)),
)
#: what the truth simulator may use of the engine: a shared bug must not cancel out
SIM_MAY_IMPORT = ("gcs_core.units", "gcs_core.errors")
#: third-party packages each side must never import
FORBIDDEN = {"gcs_core": ("textual", "rich"), "gcs_tui": ("h5py",)}


def _modules() -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, is a package ``__init__``)."""
    found = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            is_pkg = parts[-1] == "__init__"
            found[".".join(parts[:-1] if is_pkg else parts)] = (path, is_pkg)
    return found


MODULES = _modules()


def _targets(module: str, is_pkg: bool, node: ast.Import | ast.ImportFrom) -> list[str]:
    """Dotted names an import statement reaches (``from pkg import sub`` reaches ``pkg.sub``)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if node.level:
        base = module.split(".")[: len(module.split(".")) - (0 if is_pkg else 1)]
        base = base[: len(base) - (node.level - 1)]
        source = ".".join(base + ([node.module] if node.module else []))
    else:
        source = node.module or ""
    return [f"{source}.{a.name}" if f"{source}.{a.name}" in MODULES else source for a in node.names]


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _graph() -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """(module -> internal modules it imports, module -> third-party top-level names)."""
    internal: dict[str, set[str]] = defaultdict(set)
    external: dict[str, set[str]] = defaultdict(set)
    for module, (path, is_pkg) in MODULES.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        typing_only = {
            id(n)
            for block in ast.walk(tree)
            if isinstance(block, ast.If) and _is_type_checking(block.test)
            for stmt in block.body
            for n in ast.walk(stmt)
        }
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Import, ast.ImportFrom)) or id(node) in typing_only:
                continue
            for target in _targets(module, is_pkg, node):
                if target.split(".")[0] not in PACKAGES:
                    external[module].add(target.split(".")[0])
                    continue
                while target and target not in MODULES:
                    target = target.rpartition(".")[0]
                if target and target != module:
                    internal[module].add(target)
    return internal, external


INTERNAL, EXTERNAL = _graph()


def _cycles(nodes, edges) -> list[list[str]]:
    """Strongly connected components with more than one node (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    counter = 0
    for root in sorted(nodes):
        if root in index:
            continue
        work = [(root, iter(sorted(edges.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(edges.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    component.append(top)
                    if top == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def _package(module: str) -> str:
    """The package a module belongs to (``gcs_core.estimators.batch.least_squares`` -> ``gcs_core.estimators``;
    a top-level module is its own package)."""
    parts = module.split(".")
    return module if MODULES[module][1] or len(parts) <= 2 else ".".join(parts[:2])


def _layer(module: str) -> int:
    best, rank = -1, None
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best:
                best, rank = len(p), i
    assert rank is not None, f"{module} is in no layer: add it to LAYERS in {__file__}"
    return rank


def _split(side: str) -> tuple[set[str], dict[str, set[str]]]:
    nodes = {m for m in MODULES if m.split(".")[0] == side}
    return nodes, {m: {t for t in INTERNAL.get(m, ()) if t in nodes} for m in nodes}


@pytest.mark.parametrize("side", ["gcs_core", "gcs_tui"])
def test_no_module_imports_itself_round_a_cycle(side):
    nodes, edges = _split(side)
    assert _cycles(nodes, edges) == []


@pytest.mark.parametrize("side", ["gcs_core", "gcs_tui"])
def test_no_package_imports_itself_round_a_cycle(side):
    nodes, edges = _split(side)
    packages: dict[str, set[str]] = defaultdict(set)
    for a, targets in edges.items():
        for b in targets:
            if _package(a) != _package(b):
                packages[_package(a)].add(_package(b))
    assert _cycles({_package(m) for m in nodes}, packages) == []


def test_every_import_goes_down_the_layers():
    upward = sorted(
        f"{a} ({LAYERS[_layer(a)][0]}) imports {b} ({LAYERS[_layer(b)][0]})"
        for a, targets in INTERNAL.items()
        for b in targets
        if _layer(b) > _layer(a)
    )
    assert upward == []


def test_the_simulator_imports_nothing_of_the_engine_but_units_and_errors():
    """The truth simulator must not share code with the models it checks."""
    leaks = sorted(
        f"{a} imports {b}"
        for a, targets in INTERNAL.items()
        if a.startswith("gcs_core.sim")
        for b in targets
        if not b.startswith("gcs_core.sim") and b not in SIM_MAY_IMPORT
    )
    assert leaks == []


@pytest.mark.parametrize("side", sorted(FORBIDDEN))
def test_each_side_keeps_off_the_others_libraries(side):
    leaks = sorted(
        f"{m} imports {x}"
        for m, names in EXTERNAL.items()
        if m.split(".")[0] == side
        for x in names
        if x in FORBIDDEN[side]
    )
    assert leaks == []


def test_no_module_level_getattr_shims():
    """No PEP 562 ``__getattr__`` re-exporting another module's names on first use."""
    shims = sorted(
        m
        for m, (path, _) in MODULES.items()
        if any(isinstance(n, ast.FunctionDef) and n.name == "__getattr__" for n in ast.parse(path.read_text()).body)
    )
    assert shims == []


def test_the_walk_sees_the_tree():
    """A guard on the walk itself: it finds the layers' packages and their imports."""
    assert {"gcs_core.problem.build", "gcs_core.io.importer", "gcs_tui.tui.app"} <= set(MODULES)
    assert "gcs_core.problem.state" in INTERNAL["gcs_core.problem.build"]
    assert "h5py" in EXTERNAL["gcs_core.io.h5store"]
    assert _cycles({"a", "b", "c"}, {"a": {"b"}, "b": {"c"}, "c": {"a"}}) == [["a", "b", "c"]]
