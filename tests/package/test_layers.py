"""The layers of docs/architecture.md, checked on the imports of every module (module level and inside functions):

- planar_lcp/engine/ imports nothing of planar_lcp outside engine/ (it knows no Scene);
- planar_lcp/frames.py (rotations, body frame <-> centre of mass) imports nothing of planar_lcp: every layer above
  the engine may use it;
- planar_lcp/spec/ imports nothing of planar_lcp outside spec/ but frames.py (it runs no simulation);
- the core (every other module of planar_lcp except viz, cli, bridges/, studies/, benchmarks/ and parallel/) imports
  none of them; nothing in planar_lcp imports planners (test_package.py also checks that it never names them) or
  ompl (the planners alone do).
"""

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[2] / "planar_lcp"


def module_name(path):
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_modules(path):
    """Absolute names of the modules `path` imports (relative imports resolved)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module_name(path) if path.name == "__init__.py" else module_name(path).rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)   # `from planar_lcp import viz`
    return out


def layer(name):
    parts = name.split(".")
    if len(parts) > 1 and parts[1] in ("engine", "spec", "bridges", "studies", "benchmarks", "parallel", "viz",
                                            "cli", "frames"):
        return parts[1]
    return "core"


MODULES = sorted(PKG.rglob("*.py"))
#: layer -> layers of planar_lcp it may import
ALLOWED = {"engine": {"engine"}, "frames": set(), "spec": {"spec", "frames"},
           "core": {"core", "engine", "spec", "frames"}}


def test_every_module_is_found():
    names = {module_name(p) for p in MODULES}
    assert {"planar_lcp.sim", "planar_lcp.engine.step", "planar_lcp.spec.scene", "planar_lcp.cli"} <= names


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PKG.parent)))
def test_imports_respect_the_layers(path):
    me = layer(module_name(path))
    for mod in imported_modules(path):
        top = mod.split(".")[0]
        assert top not in ("planners", "ompl"), f"{path}: imports {mod}"   # planners alone imports OMPL
        if top != "planar_lcp" or mod == "planar_lcp" or me not in ALLOWED:
            continue
        # `from planar_lcp import x` is recorded both as planar_lcp and as planar_lcp.x: judge the longer name
        assert layer(mod) in ALLOWED[me], f"{path} ({me}) imports {mod} ({layer(mod)})"


def _runtime_nodes(tree):
    """ast.walk without the bodies of `if TYPE_CHECKING:`."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        if isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING":
            todo.extend(node.orelse)
            continue
        todo.extend(ast.iter_child_nodes(node))


def _import_graph():
    """module -> the modules of planar_lcp and planners it imports (module level and inside functions); a package
    named only as the place a module is imported from (`from planar_lcp.engine import step`) is not counted, nor an
    import for type checkers only (`if TYPE_CHECKING:`), which never runs."""
    roots = [PKG, PKG.parent / "planners"]
    paths = {module_name(p): p for root in roots for p in sorted(root.rglob("*.py"))}
    graph = {}
    for name, path in paths.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        out = set()
        for node in _runtime_nodes(tree):
            if isinstance(node, ast.Import):
                out.update(a.name for a in node.names if a.name in paths)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[:len(base) - (node.level - 1)]
                    mod = ".".join(base + ([node.module] if node.module else []))
                else:
                    mod = node.module
                subs = {f"{mod}.{a.name}" for a in node.names} & paths.keys()
                out.update(subs)
                if len(subs) < len(node.names) and mod in paths:
                    out.add(mod)
        graph[name] = out - {name}
    return graph


def test_no_import_circle():
    """No two modules of planar_lcp and planners import each other, directly or through others (Tarjan's strongly
    connected components of the import graph, every import counted, those inside functions too)."""
    graph = _import_graph()
    index, low, stack, on, circles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                circles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert not circles, circles
    assert graph["planar_lcp.engine.solvers.lemke"] >= {"planar_lcp.engine.solvers.block_lemke",
                                                        "planar_lcp.engine.solvers.certificate"}


ROOM_NAMES = {"planners": "`planners/`", "environments": "`planners/environments/`",
              "studies": "`planar_lcp/studies/`", "benchmarks": "`planar_lcp/benchmarks/`",
              "bridges": "`planar_lcp/bridges/`", "parallel": "`planar_lcp/parallel/`", "cli": "`planar_lcp/cli.py`",
              "viz": "`planar_lcp/viz.py`", "core": "core", "compilation": "`planar_lcp/compilation/`",
              "spec": "`planar_lcp/spec/`", "geometry": "`planar_lcp/geometry.py`", "frames": "`planar_lcp/frames.py`",
              "engine": "`planar_lcp/engine/`", "derivatives": "`planar_lcp/derivatives/`"}


def _room(module):
    parts = module.split(".")
    if parts[0] == "planners":
        return "environments" if parts[1:2] == ["environments"] else "planners"
    if len(parts) > 1 and parts[1] in ROOM_NAMES:
        return parts[1]
    return "core"


def test_architecture_md_draws_the_rooms_imports_as_they_are():
    text = (PKG.parent / "docs" / "architecture.md").read_text()
    section = text.split("## Rooms and their imports", 1)[1].split("\n## ", 1)[0]
    by_label = {label: key for key, label in ROOM_NAMES.items()}
    drawn = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")] if line.startswith("| ") else []
        if len(cells) == 2 and cells[0] in by_label:
            drawn[by_label[cells[0]]] = {c.strip() for c in cells[1].split(",") if c.strip()}
    actual = {key: set() for key in ROOM_NAMES}
    for a, imported in _import_graph().items():
        for b in imported:
            if _room(a) != _room(b):
                actual[_room(a)].add(_room(b))
    assert drawn == actual
