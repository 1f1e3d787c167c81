"""The Cycles reference of a scene's frame, rendered once and cached by a hash of everything it depends on."""
import ast
import hashlib
import json
import os
from dataclasses import dataclass

import bpy
import numpy as np

from ssr_addon.batch.frame import render_frame
from ssr_addon.batch.outputs import prepare_output_folder, write_exr, write_json, written_together
from ssr_addon.batch.request import RenderRequest
from ssr_addon.blender import render_passes, render_setup
from ssr_addon.blender.overrides import TemporaryChanges
from .images import layer_rgb, read_channels
from .metrics import flip_error, reflective_mask
from .scenes import scene_label

DEFAULT_CACHE = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"),
                             "stochastic-ssr", "references")
# Two Cycles renders of half the samples each, with different seeds: their mean
# is the reference and their difference measures the reference's own noise.
REFERENCE_SAMPLES = 2048
REFERENCE_SEEDS = (0, 1)
CACHE_FORMAT = 1


def _file_digest(digest, path):
    with open(path, "rb") as stream:
        digest.update(stream.read())


def scene_digest(path):
    """Hash of a scene file and, for a builder script, the sibling modules it imports."""
    digest = hashlib.sha256()
    _file_digest(digest, path)
    if path.endswith(".py"):
        with open(path, encoding="utf-8") as source:
            tree = ast.parse(source.read())
        modules = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
        modules |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module}
        for module in sorted(modules):
            sibling = os.path.join(os.path.dirname(path), f"{module}.py")
            if os.path.isfile(sibling):
                _file_digest(digest, sibling)
    return digest.hexdigest()


def reference_key(scene_path, resolution, samples, frame):
    """Everything the reference depends on: the scene, how it is rendered, where and when."""
    digest = hashlib.sha256()
    for module in (render_setup, render_passes):  # how the passes are rendered
        _file_digest(digest, module.__file__)
    digest.update(json.dumps({"format": CACHE_FORMAT, "scene": scene_digest(scene_path),
                              "resolution": list(resolution), "samples": samples, "frame": frame,
                              "seeds": REFERENCE_SEEDS, "blender": bpy.app.version_string}).encode())
    return digest.hexdigest()[:24]


@dataclass
class Reference:
    image: np.ndarray           # (H, W, 3) scene linear
    roughness: np.ndarray
    specular_color: np.ndarray
    info: dict                  # samples, render milliseconds, noise, cached

    @property
    def mask(self):
        return reflective_mask(self.roughness, self.specular_color)


def _cache_paths(scene_path, resolution, samples, frame, cache_dir):
    key = reference_key(scene_path, resolution, samples, frame)
    return tuple(os.path.join(cache_dir, f"{key}.{ext}") for ext in ("exr", "json"))


def cached_reference(scene_path, resolution, samples, frame, cache_dir):
    """The Cycles reference of FRAME of the scene at SCENE_PATH where the cache holds it, else None."""
    image_path, info_path = _cache_paths(scene_path, resolution, samples, frame, cache_dir)
    if not (os.path.isfile(image_path) and os.path.isfile(info_path)):
        return None
    with open(info_path, encoding="utf-8") as stream:
        info = dict(json.load(stream), cached=True)
    channels = read_channels(image_path)
    return Reference(layer_rgb(channels, "Reference"), channels["Roughness.V"], layer_rgb(channels, "Specular Color"),
                     info)


def render_reference(scene, scene_path, resolution, samples, frame, cache_dir, log=print):
    """The Cycles reference of FRAME, from the cache or rendered once and stored there."""
    cached = cached_reference(scene_path, resolution, samples, frame, cache_dir)
    if cached is not None:
        return cached
    image_path, info_path = _cache_paths(scene_path, resolution, samples, frame, cache_dir)
    prepare_output_folder(cache_dir)
    scene.frame_set(frame)
    halves, milliseconds = [], 0.0
    for seed in REFERENCE_SEEDS:
        with TemporaryChanges() as changes:
            changes.set(scene.cycles, "seed", seed)
            images, timer = render_frame(scene, RenderRequest(out_dir=cache_dir, method="cycles", resolution=resolution,
                                                              samples=samples // len(REFERENCE_SEEDS)))
        halves.append(images)
        milliseconds += sum(timer.milliseconds.values())
    first, second = (half.final[..., :3] for half in halves)
    passes = halves[0].passes
    image = (first + second) / 2
    info = {
        "samples": samples, "frame": frame, "render_ms": round(milliseconds, 1),
        # The mean of two halves has half the variance of either: its noise is |a - b| / 2.
        "noise_rmse": float(np.sqrt(np.mean((first - second) ** 2)) / 2),
        "noise_flip_reflective": flip_error(first, second, reflective_mask(passes.roughness, passes.specular_color)),
    }
    channels = {}
    for layer, array in (("Reference", image), ("Specular Color", passes.specular_color)):
        channels.update({f"{layer}.{c}": array[..., index] for index, c in enumerate("RGB")})
    channels["Roughness.V"] = passes.roughness
    with written_together([image_path]) as (partial,):
        write_exr(partial, channels)
    write_json(info_path, info)  # last: an entry counts as cached once both files are there
    log(f"reference {scene_label(scene_path)} frame {frame}: {samples} samples, {milliseconds / 1000:.1f} s")
    return Reference(image, passes.roughness, passes.specular_color, dict(info, cached=False))
