"""Shared by the benchmarks: 1600x900 inputs (the copy-pass yardstick is ssr_addon.bench.copy_pass_ms)."""
import os
import sys

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)

from ssr_addon.gpu_backend import ensure_backend  # noqa: E402
from ssr_addon.passes import FramePasses, render_passes  # noqa: E402
from ssr_addon.scene_io import load_scene  # noqa: E402

SIZE = (1600, 900)


def upscaled_passes(scene_name="mirror_floor", factor=5):
    """The scene's passes rendered at SIZE / factor and repeated up to SIZE: real content at the
    benchmark's pixel count, without a minutes-long software render."""
    scene = load_scene(os.path.join(REPO, "test_scenes", f"{scene_name}.py"))
    small = render_passes(scene, "eevee", samples=4, resolution=(SIZE[0] // factor, SIZE[1] // factor))
    fields = {}
    for name, value in vars(small).items():
        if isinstance(value, np.ndarray) and value.shape[:2] == small.depth.shape:
            value = value.repeat(factor, axis=0).repeat(factor, axis=1)
        fields[name] = value
    ensure_backend()
    return scene, FramePasses(**fields)
