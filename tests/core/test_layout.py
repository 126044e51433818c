"""The shape of core/ (docs/architecture.md), checked by parsing it with ``ast``:

- no import cycle between core modules, counting imports inside functions too;
- no private name (leading underscore) used across modules: neither
  ``from .x import _name`` nor ``x._name`` on an imported core module;
- packages import only packages ranked below them (RANKS), and core never imports bpy.
"""

import ast
import pathlib


CORE = pathlib.Path(__file__).resolve().parents[2] / "core"

RANKS = {
    "_numba_cache": 0, "sampling": 0, "color": 0, "spectral": 0, "settings": 0, "presets": 0,
    "passes": 0,
    "scene": 1, "io": 1,
    "materials": 2, "lights": 2, "media": 2, "memory": 2, "shading": 2,
    "prepared": 3,
    "photons": 4,
    "integrators": 5,
    "api": 6, "__init__": 7,
}
"""Rank of each top-level module or package of core/: an import must go to a lower rank, or
stay inside its own package (modules of rank 0 may import each other)."""


def modules():
    """{dotted name under core: path} of every core source file."""
    found = {}
    for path in sorted(CORE.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        parts = list(path.relative_to(CORE).with_suffix("").parts)
        if parts[-1] == "__init__" and len(parts) > 1:
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


MODULES = modules()


def package_of(name: str) -> str:
    """The dotted package a module's relative imports start from."""
    path = MODULES[name]
    rel = path.relative_to(CORE).with_suffix("").parts
    return ".".join(rel[:-1])


def resolve(name: str, node: ast.ImportFrom) -> list[tuple[str, list[str]]]:
    """[(imported core module, [names imported from it])] of one relative import."""
    base = package_of(name).split(".") if package_of(name) else []
    if node.level - 1 > len(base):
        raise AssertionError(f"{name}: import above core")
    base = base[:len(base) - (node.level - 1)]
    target = ".".join(base + (node.module.split(".") if node.module else []))
    out = []
    for a in node.names:
        sub = ".".join(filter(None, [target, a.name]))
        if sub in MODULES:  # from ..scene import geometry: the module itself
            out.append((sub, []))
        else:
            out.append((target or "__init__", [a.name]))
    return out


def imports():
    """{module: [(imported module, names, line)]} for every relative import in core."""
    graph = {}
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text(), str(path))
        edges = []
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level > 0:
                for target, names in resolve(name, node):
                    edges.append((target, names, node.lineno))
            elif isinstance(node, ast.Import):
                for a in node.names:
                    assert a.name.split(".")[0] != "bpy", f"core/{name} imports bpy"
            elif isinstance(node, ast.ImportFrom) and node.module:
                assert node.module.split(".")[0] != "bpy", f"core/{name} imports bpy"
        graph[name] = edges
    return graph


GRAPH = imports()


def top(name: str) -> str:
    return name.split(".")[0]


def test_every_core_module_has_a_rank():
    assert {top(m) for m in MODULES} <= set(RANKS), {top(m) for m in MODULES} - set(RANKS)


def cycles(graph) -> list[str]:
    """Import cycles of a {module: [(target, names, line)]} graph, as "a -> b -> a"."""
    state, found = {}, []

    def visit(node, stack):
        state[node] = 1
        for target, _, _ in graph.get(node, []):
            if target == node or target not in graph:
                continue
            if state.get(target) == 1:
                found.append(" -> ".join(stack[stack.index(target):] + [target]))
            elif state.get(target) is None:
                visit(target, stack + [target])
        state[node] = 2

    for m in sorted(graph):
        if state.get(m) is None:
            visit(m, [m])
    return found


def private_imports(graph) -> list[str]:
    """``from .x import _name`` across modules."""
    return [f"core/{name}:{line} imports {n} from {target}"
            for name, edges in graph.items() for target, names, line in edges
            if target != name for n in names if n.startswith("_") and n != "_numba_cache"]


def private_attributes() -> list[str]:
    """``x._name`` on a core module (or anything) imported by a relative import."""
    bad = []
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text())
        aliases = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level > 0:
                for a in node.names:
                    aliases.add(a.asname or a.name)
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in aliases and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                bad.append(f"core/{name}:{node.lineno} uses {node.value.id}.{node.attr}")
    return bad


def upward_imports(graph) -> list[str]:
    """Imports of a package ranked at or above the importer's (RANKS)."""
    bad = []
    for name, edges in graph.items():
        src = top(name)
        for target, _, line in edges:
            dst = top(target)
            if dst == src or RANKS[src] == RANKS[dst] == 0:
                continue
            if RANKS[dst] >= RANKS[src]:
                bad.append(f"core/{name}:{line} (rank {RANKS[src]}) imports {target} "
                           f"(rank {RANKS[dst]})")
    return bad


def function_imports() -> list[str]:
    """Relative imports inside functions (the way a cycle hides)."""
    bad = []
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text())
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(fn):
                    if isinstance(node, ast.ImportFrom) and node.level > 0:
                        bad.append(f"core/{name}:{node.lineno} imports a core module inside "
                                   f"{fn.name}()")
    return bad


def test_no_import_cycle():
    assert not cycles(GRAPH), cycles(GRAPH)


def test_no_private_name_crosses_a_module():
    bad = private_imports(GRAPH) + private_attributes()
    assert not bad, "\n".join(bad)


def test_packages_import_only_downwards():
    bad = upward_imports(GRAPH)
    assert not bad, "\n".join(bad)


def test_no_core_import_inside_a_function():
    bad = function_imports()
    assert not bad, "\n".join(bad)


def test_the_checks_catch_what_they_forbid():
    """Each rule reports a made-up violation (so the tests above can fail)."""
    def with_edge(src, target, names=()):
        fake = dict(GRAPH)
        fake[src] = list(fake[src]) + [(target, list(names), 1)]
        return fake

    assert cycles(with_edge("scene.geometry", "integrators.sppm"))
    assert private_imports(with_edge("api", "integrators.sppm", ["_passes"]))
    assert upward_imports(with_edge("scene.geometry", "photons.tracing"))
    assert upward_imports(with_edge("materials.bsdf", "lights.light_set"))  # same rank
