"""The house's rules, read from the code's own text (ast): each layer of the render core imports only
from the layers below it, no import cycles, bpy only in the Blender boundary, and no import inside a
function but the lazy loads of heavy optional modules named here."""
import ast
from pathlib import Path

CORE = Path(__file__).resolve().parent.parent / "smbs_addon"
# bottom to top; a layer may import from any layer before it (io sits beside scene: files only)
LAYERS = ["core", "scene", "io", "shading", "kernels", "trace", "paths", "walks", "baking", "blender", "cli"]
# modules a function may import lazily, on purpose: bpy and OpenImageIO are heavy and optional where
# an .npz is baked or nothing is written; numba's internals are looked up where they are used
LAZY = {"bpy", "OpenImageIO", "numba.core", "numba.core.caching", "numba.core.event", "llvmlite.binding", "embreex",
        "embreex.rtcore_scene", "tempfile", "pathlib", "importlib", "subprocess"}


def _modules():
    for p in sorted(CORE.rglob("*.py")):
        parts = p.relative_to(CORE).with_suffix("").parts
        yield parts, ast.parse(p.read_text())


def _imports(parts, tree):
    """(target sub-package or None, lineno, inside a function, module name) of every import."""
    pkg = list(parts[:-1])
    out = []

    def visit(node, inside):
        for ch in ast.iter_child_nodes(node):
            if isinstance(ch, ast.ImportFrom):
                if ch.level:
                    base = pkg[:len(pkg) - ch.level + 1] + (ch.module.split(".") if ch.module else [])
                    names = [base + [a.name] for a in ch.names] if not base else [base]
                    out.append((names[0][0] if names[0] else None, ch.lineno, inside, ".".join(names[0])))
                else:
                    out.append((None, ch.lineno, inside, ch.module or ""))
            elif isinstance(ch, ast.Import):
                for a in ch.names:
                    out.append((None, ch.lineno, inside, a.name))
            visit(ch, inside or isinstance(ch, (ast.FunctionDef, ast.AsyncFunctionDef)))
    visit(tree, False)
    return out


def test_each_layer_imports_only_from_layers_below():
    wrong = []
    for parts, tree in _modules():
        if len(parts) < 2:  # smbs_addon/__init__.py and __main__.py sit on top of everything
            continue
        layer = LAYERS.index(parts[0])
        for target, line, _, name in _imports(parts, tree):
            if target in LAYERS and LAYERS.index(target) > layer:
                wrong.append(f"{'/'.join(parts)}.py:{line} imports {name} (layer {target} above {parts[0]})")
    assert not wrong, "\n".join(wrong)


def test_bpy_only_in_the_blender_boundary():
    users = {"/".join(parts) for parts, tree in _modules()
             for _, _, _, name in _imports(parts, tree) if name.split(".")[0] == "bpy"}
    assert users and all(u.startswith("blender/") for u in users), sorted(users)


def test_no_import_inside_a_function_but_the_lazy_ones():
    inside = [f"{'/'.join(parts)}.py:{line} {name}" for parts, tree in _modules()
              for target, line, lazy, name in _imports(parts, tree)
              if lazy and (target is not None or name not in LAZY)]
    # the command line loads the Blender boundary (and with it bpy, seconds) only for a .blend input
    inside = [s for s in inside if not (s.startswith("cli/inputs.py") and s.split()[-1] == "blender.open_blend")]
    assert not inside, "\n".join(inside)


def test_no_import_cycles():
    graph = {}
    for parts, tree in _modules():
        me = ".".join(parts)
        graph[me] = {name for target, _, _, name in _imports(parts, tree) if target in LAYERS}
    known = set(graph)

    def module_of(name):
        while name and name not in known:
            name = name.rpartition(".")[0]
        return name
    graph = {m: {module_of(n) for n in ns} - {"", m} for m, ns in graph.items()}
    graph = {m: {n for n in ns if not n.endswith("__init__") and n in known} for m, ns in graph.items()}
    seen, cycles = set(), []

    def visit(m, path):
        if m in path:
            cycles.append(path[path.index(m):] + [m])
            return
        if m in seen:
            return
        seen.add(m)
        for n in graph.get(m, ()):
            visit(n, path + [m])
    for m in sorted(graph):
        visit(m, [])
    assert not cycles, cycles[:3]
