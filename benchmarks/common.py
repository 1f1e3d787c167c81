"""Shared by the benchmarks: 1600x900 inputs (the copy-pass yardstick is ssr_addon.bench.copy_pass_ms)."""
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)

from ssr_addon.bench.speed import COPY_PASS_LARGE as SIZE  # noqa: E402
from ssr_addon.bench.speed import upscaled_passes as upscaled_scene_passes  # noqa: E402
from ssr_addon.scene_io import load_scene  # noqa: E402


def upscaled_passes(scene_name="mirror_floor"):
    """(the scene, its passes at SIZE: ssr_addon.bench.speed.upscaled_passes)."""
    scene = load_scene(os.path.join(REPO, "test_scenes", f"{scene_name}.py"))
    return scene, upscaled_scene_passes(scene, SIZE)
