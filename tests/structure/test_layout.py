"""The house rules of the source tree, checked on the source itself (no imports of the code).

- no module imports another module's ``_private`` name;
- ``localizer`` imports neither ``agvsim`` nor ``envs``; ``envs`` holds no physics or vision
  (no pymunk, pyrender, OpenGL, cv2 kernels of its own);
- the layers import one way: world -> vehicle -> sensors -> loop -> analysis (CLI and envs on top);
- no import cycle between modules (module-level imports);
- no source module over 450 lines.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("agvsim", "localizer", "envs")
MAX_LINES = 450

#: agvsim modules every layer may import (utilities with no agvsim imports of their own)
SHARED = {"files"}
#: agvsim layer -> layers it may import (besides itself, localizer and SHARED)
LAYERS = {
    "world": set(),
    "vehicle": {"world"},
    "sensors": {"world", "vehicle"},
    "loop": {"world", "vehicle", "sensors"},
    "analysis": {"world", "vehicle", "sensors", "loop"},
    # deployment tools (the target layout planner, printable targets): read maps, predict the filter
    "deploy": {"world", "vehicle", "sensors", "loop", "analysis"},
    # recordings of runs (read the loop's records); logged drives (written from a loop, replayed
    # through the same filter set-up and drawn with the analysis pictures)
    "record": {"world", "vehicle", "sensors", "loop"},
    "replay": {"world", "vehicle", "sensors", "loop", "analysis", "record"},
    # a sweep is a command's work: it shares the commands' run folder, workers and flag parsers
    "sweep": {"world", "vehicle", "sensors", "loop", "analysis", "commands"},
}


def _modules():
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            yield ".".join(parts), path


MODULES = dict(_modules())


def _imports(path: Path, top_level_only: bool = False):
    """(module imported, names, line) for each absolute import of a project module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    nodes = tree.body if top_level_only else ast.walk(tree)
    for node in nodes:
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and node.module.split(".")[0] in PACKAGES:
            yield node.module, [a.name for a in node.names], node.lineno
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] in PACKAGES:
                    yield a.name, [], node.lineno


def test_the_tree_is_found():
    assert "agvsim.loop.closed_loop" in MODULES and "localizer.numeric" in MODULES and "envs.tasks" in MODULES


def test_no_module_imports_another_modules_private_name():
    bad = []
    tests = {".".join(p.relative_to(ROOT).with_suffix("").parts): p for p in sorted((ROOT / "tests").rglob("*.py"))}
    for name, path in {**MODULES, **tests}.items():
        for module, names, line in _imports(path):
            if module == name:
                continue
            bad += [f"{path.relative_to(ROOT)}:{line}: {module}.{n}" for n in names
                    if n.startswith("_") and not n.startswith("__")]
    assert bad == []


def test_localizer_runs_without_the_simulator():
    bad = [f"{path.relative_to(ROOT)}:{line}: {module}" for name, path in MODULES.items()
           if name.startswith("localizer") for module, _, line in _imports(path)
           if module.split(".")[0] in ("agvsim", "envs")]
    assert bad == []


def test_envs_hold_no_physics_or_vision():
    heavy = ("pymunk", "pyrender", "OpenGL")
    bad = []
    for name, path in MODULES.items():
        if not name.startswith("envs"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            mods = []
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                mods = [node.module]
            bad += [f"{path.relative_to(ROOT)}: {m}" for m in mods
                    if m.split(".")[0] in heavy or m.startswith(("agvsim.vehicle.physics", "agvsim.sensors.render"))]
    assert bad == []


def test_agvsim_layers_import_one_way():
    bad = []
    for name, path in MODULES.items():
        parts = name.split(".")
        if parts[0] != "agvsim" or len(parts) < 2 or parts[1] not in LAYERS:
            continue
        layer = parts[1]
        for module, _, line in _imports(path):
            mp = module.split(".")
            if mp[0] != "agvsim":
                continue
            if len(mp) < 2 or mp[1] == layer or mp[1] in SHARED:
                continue
            if mp[1] not in LAYERS[layer]:
                bad.append(f"{path.relative_to(ROOT)}:{line}: {layer} imports {module}")
    assert bad == []


def _resolve(module: str) -> str | None:
    while module and module not in MODULES:
        module = module.rpartition(".")[0]
    return module or None


def test_no_import_cycle_between_modules():
    graph = {}
    for name, path in MODULES.items():
        deps = set()
        for module, names, _ in _imports(path, top_level_only=True):
            for target in [f"{module}.{n}" for n in names] + [module]:
                r = _resolve(target)
                if r and r != name:
                    deps.add(r)
                    break
        graph[name] = deps
    # a package's __init__ importing its own submodules is how Python packages work: not a cycle
    for name in graph:
        graph[name] = {d for d in graph[name] if not (d.startswith(name + "."))}
    assert "agvsim.loop.closed_loop" in graph["agvsim.loop.mission"]  # the graph sees imports
    state, cycles = {}, []

    def visit(node, stack):
        state[node] = 1
        for dep in graph.get(node, ()):
            if state.get(dep) == 1:
                cycles.append(" -> ".join(stack[stack.index(dep):] + [dep]) if dep in stack else f"{node} -> {dep}")
            elif dep not in state:
                visit(dep, stack + [dep])
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert cycles == []


@pytest.mark.parametrize("name", sorted(MODULES))
def test_module_is_small(name):
    lines = MODULES[name].read_text(encoding="utf-8").count("\n")
    assert lines <= MAX_LINES, f"{name}: {lines} lines"
