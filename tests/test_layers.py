"""The package layout follows the data flow (issue 21; ``CONTRIBUTING.md``).

sensor (``whisker_io``) -> front end (``cansim.frontends``) -> attractor engine (the
top level of ``cansim``: axes, params, kernels, backends, population, path integration,
decoding, local view, spiking) -> map (``maps``) -> model (``cansim.models``) ->
explorer (``cansim.explore``) -> study (``cansim.studies``, ``cansim.experiments``, and the
synthetic worlds and conformance suite of ``cansim.testing``) -> tools (``cansim.tools``,
``python -m cansim``).

Every import statement of every module is read from its source (module level and inside
functions, so a function-level import cannot hide a backwards edge or a cycle; imports
under ``if TYPE_CHECKING:`` are not run and are left out), and checked against that order
for every pair of stages.
"""

from __future__ import annotations

import ast
import importlib
import sys
import warnings
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("whisker_io", "maps", "cansim")

#: (stage, module prefixes) in data-flow order; the longest matching prefix decides.
STAGES: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("sensor", ("whisker_io",)),
    ("front end", ("cansim.frontends",)),
    ("engine", ("cansim",)),
    ("map", ("maps",)),
    ("model", ("cansim.models",)),
    ("explorer", ("cansim.explore",)),
    ("study", ("cansim.studies", "cansim.experiments", "cansim.testing")),
    ("tools", ("cansim.tools", "cansim.__main__")),
)


def stage_of(module: str) -> int:
    best, best_len = -1, -1
    for i, (_, prefixes) in enumerate(STAGES):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best_len:
                best, best_len = i, len(p)
    return best


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST, module: str, is_package: bool, modules: frozenset[str] = frozenset()) -> set[str]:
    """Absolute names of the modules a source imports (at any depth).

    ``from pkg import name`` depends on ``pkg.name`` when that is one of ``modules``,
    else on ``pkg`` itself (a name its ``__init__`` defines or hands on).
    """
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")
                base = base if is_package else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for a in node.names:
                sub = f"{target}.{a.name}"
                found.add(sub if sub in modules else target)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


def import_graph() -> nx.DiGraph:
    files = [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")]
    modules = {_module_name(p): p for p in files}
    g = nx.DiGraph()
    g.add_nodes_from(modules)
    for name, path in modules.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        for target in _imports(tree, name, path.name == "__init__.py", frozenset(modules)):
            if target in modules and target != name:
                g.add_edge(name, target)
    return g


GRAPH = import_graph()


def test_every_module_has_a_stage():
    assert GRAPH.number_of_nodes() > 100
    assert [m for m in GRAPH if stage_of(m) < 0] == []


@pytest.mark.parametrize("earlier", range(len(STAGES)), ids=[s for s, _ in STAGES])
def test_no_stage_imports_a_later_stage(earlier):
    """For every pair (earlier, later) of stages: no module of ``earlier`` imports one of ``later``."""
    backwards = sorted(
        f"{a} ({STAGES[stage_of(a)][0]}) imports {b} ({STAGES[stage_of(b)][0]})"
        for a, b in GRAPH.edges
        if stage_of(a) == earlier and stage_of(b) > earlier
    )
    assert backwards == []


def test_no_import_cycles():
    """No two modules import each other, directly or through others, even inside functions."""
    cycles = [sorted(c) for c in nx.strongly_connected_components(GRAPH) if len(c) > 1]
    assert cycles == []


def test_stage_checker_sees_a_backwards_import(tmp_path):
    """The checker itself: a function-level import of a model from the engine is caught."""
    tree = ast.parse("def f():\n    from cansim.models.ratslam import RatSLAM\n")
    targets = _imports(tree, "cansim.population", False)
    assert "cansim.models.ratslam" in targets
    assert stage_of("cansim.population") < stage_of("cansim.models.ratslam")
    tree = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from maps import x\n")
    assert "maps" not in _imports(tree, "cansim.population", False)


def test_importing_a_front_end_does_not_load_the_engine():
    code = ("import sys, cansim.frontends.whisk; "
            "print(','.join(m for m in ('cansim.population', 'cansim.backends', 'cansim.local_view', 'cansim.models', 'maps') "
            "if m in sys.modules))")
    import subprocess

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == ""


@pytest.mark.parametrize("old", sorted(importlib.import_module("cansim._moved").MOVED))
def test_moved_modules_still_import_with_a_warning(old):
    new = importlib.import_module("cansim._moved").MOVED[old]
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=new.replace(".", r"\.")):
        module = importlib.import_module(old)
    assert module is importlib.import_module(new)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        importlib.import_module(new)  # the new path itself does not warn
