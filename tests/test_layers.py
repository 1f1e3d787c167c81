"""The architecture, held: the shipped package is four layers, each importing only those below
it, and nothing shipped imports the lab.

    core     the GPU chain: `gpu` and numpy, never bpy.data or bpy.context (no bpy at all)
    blender  render passes, captures, lights, baselines, colour management: Blender's user data
    batch    the command line, the frame loop, outputs, reports
    ui       the PropertyGroup, operators, panels, overlay, live

The imports are read from the source (ast), so the test needs neither Blender nor a GPU.
"""
import ast
import os

import pytest

from conftest import REPO

PACKAGE = "ssr_addon"
LAYERS = ("core", "blender", "batch", "ui")
# What a layer may import besides the standard library and numpy.
OUTSIDE = {"core": {"gpu", "gpu_extras"}}
# Modules that the layer order alone would allow but that must stay light: the PropertyGroup is
# imported wherever the scene's settings are, so it may not pull in the render loop.
LIGHT = {"ssr_addon.ui.properties": {"core", "blender"}}


def _module_name(path):
    relative = os.path.relpath(path, REPO)[:-len(".py")].replace(os.sep, ".")
    return relative[:-len(".__init__")] if relative.endswith(".__init__") else relative


def imports(path):
    """The absolute names of the modules PATH imports, relative imports resolved."""
    module = _module_name(path)
    package = module if path.endswith("__init__.py") else module.rpartition(".")[0]
    with open(path, encoding="utf-8") as source:
        tree = ast.parse(source.read())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[:len(package.split(".")) - node.level + 1] if node.level else []
            target = ".".join(base + ([node.module] if node.module else []))
            names.add(target)
            if not node.module:  # from . import a, b: each a module
                names.update(f"{target}.{alias.name}" for alias in node.names)
    return names


def import_graph(root=os.path.join(REPO, PACKAGE)):
    """{module: modules it imports} of every Python file under ROOT."""
    graph = {}
    for folder, _, files in os.walk(root):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                graph[_module_name(path)] = imports(path)
    return graph


def layer_of(module):
    """The layer of a module of the package, None for its root modules and anything outside it."""
    parts = module.split(".")
    if parts[0] != PACKAGE or len(parts) < 2 or parts[1] not in LAYERS:
        return None
    return parts[1]


def violations(graph):
    """Each import that breaks the architecture, as a line naming it."""
    found = []
    for module, imported in sorted(graph.items()):
        layer = layer_of(module)
        for target in sorted(imported):
            top = target.split(".")[0]
            if top == "lab":
                found.append(f"{module} imports the lab ({target})")
            if layer is None:
                continue
            target_layer = layer_of(target)
            if target_layer is not None and LAYERS.index(target_layer) > LAYERS.index(layer):
                found.append(f"{module} ({layer}) imports {target} ({target_layer}), a layer above it")
            if module in LIGHT and target_layer is not None and target_layer not in LIGHT[module]:
                found.append(f"{module} imports {target}: it may import only {', '.join(sorted(LIGHT[module]))}")
            if layer == "core" and top not in (PACKAGE, "numpy") and top in _BLENDER_MODULES - OUTSIDE["core"]:
                found.append(f"{module} (core) imports {target}: the chain uses `gpu` only")
    return found


# Blender's own Python modules: the core may use only `gpu` (and gpu_extras) of them.
_BLENDER_MODULES = {"bpy", "bpy_extras", "bmesh", "mathutils", "blf", "gpu", "gpu_extras", "addon_utils", "bl_ui",
                    "OpenImageIO"}


def test_every_module_of_the_package_is_in_a_layer():
    stray = [module for module in import_graph() if layer_of(module) is None
             and module not in (PACKAGE, f"{PACKAGE}.__main__")]
    assert not stray, f"modules outside core/blender/batch/ui: {stray}"


def test_each_layer_imports_only_the_layers_below_it_and_never_the_lab():
    assert violations(import_graph()) == []


# The back-edges the tree had before its layers (the "One product, one lab" issue), as they
# would read now: each must be caught.
BACK_EDGES = [
    ("ssr_addon.ui.properties", "ssr_addon.batch.frame"),          # the PropertyGroup pulled in the render loop
    ("ssr_addon.blender.result_image", "ssr_addon.batch.frame"),   # debug views read the batch EXR layout
    ("ssr_addon.batch.cli", "ssr_addon.ui.operators"),             # the CLI imported the operators
    ("ssr_addon.core.chain", "ssr_addon.blender.lights"),          # the chain type-checked a lamp split
    ("ssr_addon.core.inputs", "bpy"),                              # numpy passes that drew on the GPU
    ("ssr_addon.batch.cli", "lab.bench"),                          # the CLI imported the bench
]


@pytest.mark.parametrize("module, target", BACK_EDGES)
def test_each_old_back_edge_is_caught(module, target):
    graph = import_graph()
    graph[module] = graph[module] | {target}
    caught = violations(graph)
    assert any(line.startswith(module) and target in line for line in caught), caught
