"""The project's layout, read from the source with ``ast`` (nothing is imported or run): no import circle between
its modules, the packages layered ``cliutil ◄ flightplan ◄ capture ◄ sim ◄ recon ◄ aerostereo`` (each imports only
those to its left; aerostereo is the Python entry point over them all), the render core ``sim/render/`` free of
datasets, drones, command lines and run machinery, recon's rooms layered the same way (the surface below its
appearance, nothing importing the measuring room) with only its face at its root, and no module longer than 600
lines. Each rule is checked on a small tree that breaks it too, so a rule that can no longer fail is caught."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The import packages, lowest first: each may import only those before it (and itself).
LAYERS = ("cliutil", "flightplan", "capture", "sim", "recon", "aerostereo")
#: What the render core may import from the project: itself, geodesy and the domain-free helpers.
RENDER_CORE_MAY_IMPORT = ("sim.render", "flightplan.geodesy", "cliutil")
#: Standard-library modules the render core never needs (command lines, processes).
RENDER_CORE_NEVER = ("argparse", "multiprocessing", "tqdm")
MAX_MODULE_LINES = 600
#: recon's rooms (its folders), lowest first: each may import only the rooms before it (and itself). "" is the
#: package's face, the modules at its root. The surface never imports its appearance; measuring (``measure``) imports
#: what it measures, and no room imports it (:data:`RECON_UNIMPORTED`).
RECON_ROOMS = ("inputs", "sfm", "surface", "appearance", "semantics", "run", "area", "measure", "")
RECON_UNIMPORTED = ("measure",)
#: The modules of recon's face: all its root may hold.
RECON_FACE = ("recon", "recon.__main__", "recon.cli")


def module_files(root: Path, packages=LAYERS) -> dict[str, Path]:
    """Dotted module name -> file of every module of ``packages`` under ``root`` (a package is its __init__)."""
    modules = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def imported_names(path: Path, module: str, is_package: bool) -> set[str]:
    """Every dotted name ``path`` imports, anywhere in the file (functions, ``TYPE_CHECKING`` blocks included), with
    ``from X import y`` read as ``X.y`` (a submodule or a name of ``X``) and relative imports resolved."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = module.split(".")[: None if is_package else -1]
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


def import_graph(root: Path, packages=LAYERS) -> dict[str, set[str]]:
    """Module -> the project modules it imports (the longest dotted prefix that is a module)."""
    modules = module_files(root, packages)
    graph = {}
    for module, path in modules.items():
        edges = set()
        for name in imported_names(path, module, path.name == "__init__.py"):
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name != module:
                edges.add(name)
        graph[module] = edges
    return graph


def import_circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative), each sorted."""
    index, low, on_stack, stack, circles = {}, {}, set(), [], []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, edges = work[-1]
            for nxt in edges:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        circles.append(sorted(component))
    return circles


def layering_breaks(graph: dict[str, set[str]]) -> list[str]:
    """``A -> B`` for every import of a package to the right of its own in :data:`LAYERS`."""
    rank = {package: k for k, package in enumerate(LAYERS)}
    return sorted(f"{module} -> {other}" for module, edges in graph.items() for other in edges
                  if rank[other.split(".")[0]] > rank[module.split(".")[0]])


def render_core_breaks(root: Path) -> list[str]:
    """``module: name`` for every import of a ``sim.render`` module outside what the core may import."""
    breaks = []
    for module, path in module_files(root, ("sim",)).items():
        if module != "sim.render" and not module.startswith("sim.render."):
            continue
        for name in imported_names(path, module, path.name == "__init__.py"):
            top = name.split(".")[0]
            project = top in LAYERS and not any(name == allowed or name.startswith(allowed + ".")
                                                for allowed in RENDER_CORE_MAY_IMPORT)
            if project or top in RENDER_CORE_NEVER:
                breaks.append(f"{module}: {name}")
    return sorted(breaks)


def recon_rooms(root: Path) -> dict[str, str]:
    """recon module -> its room: the folder under ``recon/`` it lives in, "" for a module at recon's root."""
    return {module: path.relative_to(root / "recon").parts[0] if path.parent != root / "recon" else ""
            for module, path in module_files(root, ("recon",)).items()}


def recon_room_breaks(graph: dict[str, set[str]], root: Path) -> list[str]:
    """``A -> B (room -> room)`` for every import between recon's rooms that :data:`RECON_ROOMS` does not allow: into
    a room at or to the right of its own, into a room of :data:`RECON_UNIMPORTED`, or from or into a room it does not
    name."""
    rooms, rank = recon_rooms(root), {room: k for k, room in enumerate(RECON_ROOMS)}
    breaks = []
    for module, room in rooms.items():
        for other in sorted(graph[module] & rooms.keys()):
            to = rooms[other]
            if to == room:
                continue
            allowed = room in rank and to in rank and rank[to] < rank[room] and to not in RECON_UNIMPORTED
            if not allowed:
                breaks.append(f"{module} -> {other} ({room or 'face'} -> {to or 'face'})")
    return sorted(breaks)


def recon_root_extras(root: Path) -> list[str]:
    """The modules at recon's root beyond its face (:data:`RECON_FACE`)."""
    return sorted(module for module, room in recon_rooms(root).items() if room == "" and module not in RECON_FACE)


def long_modules(root: Path) -> list[str]:
    """``path: lines`` of every Python file of the project (packages, tools, tests) over :data:`MAX_MODULE_LINES`."""
    files = [path for folder in (*LAYERS, "tools", "tests") for path in (root / folder).rglob("*.py")]
    return sorted(f"{path.relative_to(root)}: {count}" for path in files
                  if (count := len(path.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES)


def test_no_module_imports_itself_back():
    assert import_circles(import_graph(ROOT)) == []


def test_each_package_imports_only_those_to_its_left():
    assert layering_breaks(import_graph(ROOT)) == []


def test_the_render_core_imports_no_datasets_drones_command_lines_or_run_machinery():
    assert render_core_breaks(ROOT) == []


def test_recon_rooms_import_only_the_rooms_below_them():
    assert recon_room_breaks(import_graph(ROOT), ROOT) == []


def test_recon_root_holds_only_its_face():
    assert recon_root_extras(ROOT) == []


def test_no_module_is_longer_than_600_lines():
    assert long_modules(ROOT) == []


def write_tree(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


@pytest.fixture
def broken_tree(tmp_path):
    """A tree breaking every rule: a circle through a function-level import, two upward imports (one into the
    entry point), a render core importing argparse and the run machinery, a 601-line module at recon's root, and
    recon rooms importing against their order: the surface its appearance, the run the measuring room, the measuring
    room the face, and a room that has no place in the order."""
    return write_tree(tmp_path, {
        "cliutil/__init__.py": "",
        "flightplan/__init__.py": "",
        "flightplan/geodesy.py": "from sim.render import camera\n",
        "capture/__init__.py": "",
        "sim/__init__.py": "",
        "sim/render/__init__.py": "",
        "sim/render/camera.py": "import argparse\nfrom ..run import options\n",
        "sim/run/__init__.py": "",
        "sim/run/options.py": "def f():\n    from sim.run.frames import renderer\n",
        "sim/run/frames.py": "from sim.run import options\nrenderer = 1\n",
        "recon/__init__.py": "import aerostereo\n",
        "recon/long.py": "x = 1\n" * 601,
        "recon/cli.py": "def main():\n    return 0\n",
        "recon/surface/__init__.py": "",
        "recon/surface/mesh.py": "from recon.appearance.texture import Photo\n",
        "recon/appearance/texture.py": "Photo = 1\n",
        "recon/run/pipeline.py": "from recon.surface import mesh\nfrom ..measure import accuracy\n",
        "recon/measure/accuracy.py": "def f():\n    from recon.cli import main\n",
        "recon/kitchen/sink.py": "from recon.surface.mesh import f\n",
        "aerostereo/__init__.py": "from recon import long\n",
        "tools/ok.py": "",
        "tests/ok.py": "",
    })


def test_the_rules_catch_a_tree_that_breaks_them(broken_tree):
    graph = import_graph(broken_tree)
    assert import_circles(graph) == [["sim.run.frames", "sim.run.options"]]
    assert layering_breaks(graph) == ["flightplan.geodesy -> sim.render.camera", "recon -> aerostereo"]
    assert render_core_breaks(broken_tree) == ["sim.render.camera: argparse", "sim.render.camera: sim.run.options"]
    assert long_modules(broken_tree) == ["recon/long.py: 601"]
    assert recon_room_breaks(graph, broken_tree) == [
        "recon.kitchen.sink -> recon.surface.mesh (kitchen -> surface)",
        "recon.measure.accuracy -> recon.cli (measure -> face)",
        "recon.run.pipeline -> recon.measure.accuracy (run -> measure)",
        "recon.surface.mesh -> recon.appearance.texture (surface -> appearance)"]
    assert recon_root_extras(broken_tree) == ["recon.long"]
