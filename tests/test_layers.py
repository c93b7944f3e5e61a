"""Imports flow one way: ``rk4core`` (the system under test) imports neither
``references`` nor ``validation``; ``references`` does not import
``validation``; and no two modules import each other (at any depth of the
function bodies: a lazy import is still an edge)."""
import ast
import itertools
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGES = ("rk4core", "references", "validation")
#: A package may import these; nothing else of the harness.
ALLOWED = {"rk4core": {"rk4core"}, "references": {"rk4core", "references"},
           "validation": {"rk4core", "references", "validation"}}


def _modules() -> dict:
    mods = {}
    for pkg in PACKAGES:
        for path in (REPO / pkg).rglob("*.py"):
            parts = path.relative_to(REPO).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            mods[name] = path
    return mods


def _targets(name: str, path: Path, node, mods) -> list[str]:
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    if isinstance(node, ast.Import):
        cands = [a.name for a in node.names]
    else:
        base = node.module or ""
        if node.level:
            parts = package.split(".")
            parts = parts[:len(parts) - (node.level - 1)]
            base = ".".join(parts + ([base] if base else []))
        cands = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
    out = []
    for c in cands:
        if c.split(".")[0] not in PACKAGES:
            continue
        while c not in mods and "." in c:
            c = c.rpartition(".")[0]
        if c in mods and c != name:
            out.append(c)
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the harness modules it imports anywhere in its source."""
    mods = _modules()
    graph = {}
    for name, path in mods.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                deps.update(_targets(name, path, node, mods))
        graph[name] = deps
    return graph


GRAPH = import_graph()


def test_the_graph_sees_the_known_edges():
    # the check can fail: it finds edges that exist
    assert "validation.scenes" in GRAPH["validation.budget"]
    assert "references.dispersion" in GRAPH["references.wavepacket"]


@pytest.mark.parametrize("module", sorted(GRAPH))
def test_no_import_crosses_a_layer_upwards(module):
    allowed = ALLOWED[module.split(".")[0]]
    up = sorted(d for d in GRAPH[module] if d.split(".")[0] not in allowed)
    assert not up, f"{module} imports {up}"


def test_no_two_modules_import_each_other():
    pairs = [(a, b) for a, b in itertools.combinations(sorted(GRAPH), 2) if b in GRAPH[a] and a in GRAPH[b]]
    assert not pairs, pairs
