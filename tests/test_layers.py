"""Imports flow one way: ``rk4h`` (the folder rk4core/, the system under
test) imports neither ``rk4h.references`` nor ``rk4h.validation``;
``rk4h.references`` does not import ``rk4h.validation``; and no two modules
import each other (at any depth of the function bodies: a lazy import is
still an edge)."""
import ast
import functools
import itertools
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
#: folder -> the import name it installs as (pyproject.toml's package-dir)
PACKAGES = {"rk4core": "rk4h", "references": "rk4h.references", "validation": "rk4h.validation"}
#: A layer may import these layers; nothing else of the harness.
ALLOWED = {"rk4core": {"rk4core"}, "references": {"rk4core", "references"},
           "validation": {"rk4core", "references", "validation"}}


def layer(module: str) -> str:
    """The folder (layer) an installed module name comes from."""
    for folder in ("validation", "references"):
        if module == PACKAGES[folder] or module.startswith(PACKAGES[folder] + "."):
            return folder
    return "rk4core"


@functools.cache
def _modules() -> dict:
    mods = {}
    for folder, name0 in PACKAGES.items():
        for path in (REPO / folder).rglob("*.py"):
            parts = path.relative_to(REPO / folder).with_suffix("").parts
            parts = parts[:-1] if parts[-1] == "__init__" else parts
            mods[".".join((name0,) + parts)] = path
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
        if c.split(".")[0] != "rk4h":
            continue
        while c not in mods and "." in c:
            c = c.rpartition(".")[0]
        if c in mods and c != name:
            out.append(c)
    return out


@functools.cache
def _tree(path: Path) -> ast.Module:
    """The parsed source of ``path`` (parsed once per process; the tests only read it)."""
    return ast.parse(path.read_text(), str(path))


def import_graph() -> dict[str, set[str]]:
    """Module -> the harness modules it imports anywhere in its source."""
    mods = _modules()
    graph = {}
    for name, path in mods.items():
        deps = set()
        for node in ast.walk(_tree(path)):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                deps.update(_targets(name, path, node, mods))
        graph[name] = deps
    return graph


@pytest.fixture(scope="module")
def GRAPH():
    """The import graph, built when a test needs it (not at collection: parsing every module is seconds)."""
    return import_graph()


def test_the_graph_sees_the_known_edges(GRAPH):
    # the check can fail: it finds edges that exist
    assert "rk4h.validation.scenes" in GRAPH["rk4h.validation.budget"]
    assert "rk4h.references.dispersion" in GRAPH["rk4h.references.wavepacket"]
    assert "rk4h.models.base" in GRAPH["rk4h.references.solvers"]


def test_no_old_import_names_remain():
    """The folders' own names are not import names: a stray ``import
    validation`` would work only inside a checkout."""
    old = [f"{path}: {node.lineno}" for path in _modules().values()
           for node in ast.walk(_tree(path))
           if isinstance(node, (ast.Import, ast.ImportFrom)) and not getattr(node, "level", 0)
           and any(n.split(".")[0] in PACKAGES for n in
                   ([a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]))]
    assert not old, old


@pytest.mark.parametrize("module", sorted(_modules()))   # the keys of GRAPH
def test_no_import_crosses_a_layer_upwards(module, GRAPH):
    allowed = ALLOWED[layer(module)]
    up = sorted(d for d in GRAPH[module] if layer(d) not in allowed)
    assert not up, f"{module} imports {up}"


def test_no_two_modules_import_each_other(GRAPH):
    pairs = [(a, b) for a, b in itertools.combinations(sorted(GRAPH), 2) if b in GRAPH[a] and a in GRAPH[b]]
    assert not pairs, pairs


def _cycle(graph) -> list[str]:
    """One import cycle of ``graph`` (any length), or [] when it has none."""
    state, stack = {}, []

    def visit(v):
        state[v] = "open"
        stack.append(v)
        for w in sorted(graph.get(v, ())):
            if state.get(w) == "open":
                return stack[stack.index(w):] + [w]
            if w not in state:
                found = visit(w)
                if found:
                    return found
        state[v] = "done"
        stack.pop()
        return []

    for v in sorted(graph):
        if v not in state:
            found = visit(v)
            if found:
                return found
    return []


def test_the_cycle_search_finds_a_long_cycle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_no_import_cycle_of_any_length(GRAPH):
    """No circle, not only no pair: a -> b -> c -> a is refused too."""
    assert not _cycle(GRAPH), " -> ".join(_cycle(GRAPH))


FIGURES = PACKAGES["validation"] + ".figures"


def test_no_private_name_of_the_figures_package_is_used_outside_its_module():
    """The figure modules (style kit, scene figures, measurement figures)
    talk through public names: no ``from ...figures.style import _x`` and no
    ``F._x`` / ``kit._x`` on an imported figures module, in any module."""
    mods = _modules()
    hits = []
    for name, path in mods.items():
        tree = _tree(path)
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                for t in _targets(name, path, node, mods):
                    if not (t == FIGURES or t.startswith(FIGURES + ".")) or t == name:
                        continue
                    for a in node.names:
                        if a.name.startswith("_") and not a.name.startswith("__"):
                            hits.append(f"{path.name}:{node.lineno} imports {a.name}")
                        if t.endswith("." + a.name) or (t == FIGURES and a.name == "figures"):
                            aliases[a.asname or a.name] = t
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.startswith(FIGURES) and a.asname:
                        aliases[a.asname] = a.name
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                    and aliases[node.value.id] != name and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                hits.append(f"{path.name}:{node.lineno} uses {node.value.id}.{node.attr}")
    assert not hits, hits
