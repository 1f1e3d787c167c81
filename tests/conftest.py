"""Fixtures shared by the whole suite (one GPU backend per session, like moderngl's tests)."""
import json
import math
import os
import signal
import subprocess
import sys
import time

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = os.path.join(REPO, "test_scenes")


def pytest_collection_modifyitems(items):
    """Mark every test that uses the GPU backend `gpu`."""
    for item in items:
        if "gpu_backend" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.gpu)


@pytest.fixture(scope="session")
def gpu_backend():
    from ssr_addon.blender.gpu_context import ensure_backend
    ensure_backend()


def run_cli(*args, check=True, package="ssr_addon", timeout=600):
    """Run `python -m ssr_addon ARGS` (or PACKAGE: the lab's) in a fresh process (scene loading
    replaces the open file)."""
    result = subprocess.run([sys.executable, "-m", package, *map(str, args)], cwd=REPO,
                            capture_output=True, text=True, timeout=timeout)
    if check and result.returncode != 0:
        raise AssertionError(f"CLI failed ({result.returncode}): {result.stderr[-2000:]}")
    return result


def run_lab(*args, check=True, timeout=600):
    """Run `python -m lab ARGS` in a fresh process."""
    return run_cli(*args, check=check, package="lab", timeout=timeout)


def read_exr(path):
    """{channel name: (H, W) float32} of a single-part EXR (the bench's reader, shared)."""
    from lab.bench import read_channels
    return read_channels(str(path))


def rgb(channels, layer=None):
    from lab.bench import layer_rgb
    return layer_rgb(channels, layer)


class RenderedScene:
    """One CLI render's output folder."""

    def __init__(self, folder):
        self.folder = folder
        with open(os.path.join(folder, "report.json"), encoding="utf-8") as stream:
            self.report = json.load(stream)

    def final(self, frame=1):
        return rgb(read_exr(os.path.join(self.folder, f"frame_{frame:04d}.exr")))

    def passes(self, frame=1):
        return read_exr(os.path.join(self.folder, f"frame_{frame:04d}.passes.exr"))


@pytest.fixture(scope="session")
def render_scene(tmp_path_factory):
    """render_scene(builder, method, *extra_args) -> RenderedScene, cached per argument set."""
    cache = {}

    def render(builder, method, *extra):
        key = (builder, method, extra)
        if key not in cache:
            folder = tmp_path_factory.mktemp(f"{builder}_{method}")
            run_cli("render", os.path.join(SCENES, f"{builder}.py"), "--method", method,
                    "--out", folder, *extra)
            cache[key] = RenderedScene(str(folder))
        return cache[key]
    return render


# A cheap animation for the frame loop: one EEVEE render per frame.
DOLLY = f"""
import sys
import bpy
sys.path.insert(0, {SCENES!r})
from mirror_floor import build as build_mirror_floor


def build(scene):
    build_mirror_floor(scene)
    bpy.data.objects.remove(bpy.data.objects["Sun"])  # no lamp: one EEVEE render per frame
    scene.eevee.taa_render_samples = 4
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    scene.frame_start, scene.frame_end = 1, 5
    camera = scene.camera
    camera.location.x = -0.4
    camera.keyframe_insert("location", frame=1)
    camera.location.x = 0.4
    camera.keyframe_insert("location", frame=4)
"""


def scene_builder(tmp_path_factory, name, text):
    """A .py scene builder NAME.py holding TEXT, in a fresh folder."""
    path = tmp_path_factory.mktemp(name) / f"{name}.py"
    path.write_text(text)
    return path


@pytest.fixture(scope="session")
def dolly(tmp_path_factory):
    """A five-frame camera dolly over the mirror floor at 64x36, 4 EEVEE samples, no lamp."""
    return scene_builder(tmp_path_factory, "dolly", DOLLY)


def terminate_once_written(process, path, timeout=300):
    """SIGTERM PROCESS as soon as PATH exists (or it ended); (return code, stderr)."""
    deadline = time.monotonic() + timeout
    while not os.path.exists(path) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=timeout)
    return process.returncode, stderr


def metal_floor_under(light_type, **settings):
    """A glossy metal floor (roughness 0.3) under one light of LIGHT_TYPE with SETTINGS, lit from
    ahead of a camera looking down at it (64x36)."""
    import bpy
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    bpy.ops.mesh.primitive_plane_add(size=20)
    material = bpy.data.materials.new("Floor")
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.3
    bpy.context.active_object.data.materials.append(material)
    light = bpy.data.lights.new("Lamp", light_type)
    for name, value in settings.items():
        setattr(light, name, value)
    lamp = bpy.data.objects.new("Lamp", light)
    lamp.location = (0, 3, 1.5)
    lamp.rotation_euler = (math.radians(-70 if light_type == "SUN" else -30), 0, 0)
    scene.collection.objects.link(lamp)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0, -4, 2)
    camera.rotation_euler = (math.radians(70), 0, 0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    return scene
