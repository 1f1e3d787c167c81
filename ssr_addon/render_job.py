"""Render frames of a scene with SSR, without SSR or with Cycles, and write them out.

Shared by the command line and the operators: everything here takes the
scene and a RenderRequest, never bpy.context.
"""
import os
import re
import time
from dataclasses import asdict, dataclass, field

import bpy
import numpy as np

from .chain import ChainInputs, ChainState, run_chain
from .errors import SSRError
from .gpu_backend import StageTimer, describe_gpu, download, ensure_backend
from .outputs import prepare_output_folder, write_display_png, write_exr, write_json, write_rgba_exr
from .params import ChainSettings
from .passes import ENGINES, render_passes
from .scene_io import require_camera

# ssr: this project; none: probe/world reflections only; cycles: the path-traced
# reference; eevee-rt / eevee-rt-high: EEVEE's own screen-space ray tracing.
METHODS = ("ssr", "none", "cycles", "eevee-rt", "eevee-rt-high")
EEVEE_RAYTRACING_METHODS = {"eevee-rt": "default", "eevee-rt-high": "high"}


@dataclass
class RenderRequest:
    out_dir: str
    method: str = "ssr"
    engine: str = "eevee"
    resolution: tuple = None     # (width, height) or the scene's own
    frames: tuple = None         # (first, last) inclusive, or the scene's current frame
    samples: int = None          # EEVEE TAA samples / Cycles samples; engine default if None
    settings: ChainSettings = field(default_factory=ChainSettings)

    def __post_init__(self):
        if self.method not in METHODS:
            raise SSRError(f"unknown method {self.method!r}: expected one of {', '.join(METHODS)}")
        if self.engine not in ENGINES:
            raise SSRError(f"unknown engine {self.engine!r}: expected one of {', '.join(ENGINES)}")
        if self.method == "cycles":
            self.engine = "cycles"  # the reference is a Cycles path trace by definition
        if self.method in EEVEE_RAYTRACING_METHODS:
            self.engine = "eevee"
        if self.samples is not None and self.samples < 1:
            raise SSRError(f"--samples must be at least 1, got {self.samples}")


def parse_resolution(text):
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text or "")
    if not match or not all(4 <= int(v) <= 16384 for v in match.groups()):
        raise SSRError(f"--resolution {text!r}: expected WIDTHxHEIGHT with each side in 4..16384, e.g. 320x180")
    return int(match.group(1)), int(match.group(2))


def parse_frames(text):
    match = re.fullmatch(r"\s*(-?\d+)\s*(?:-\s*(-?\d+)\s*)?", text or "")
    if not match:
        raise SSRError(f"--frames {text!r}: expected a frame number N or a range A-B")
    first = int(match.group(1))
    last = int(match.group(2)) if match.group(2) is not None else first
    if last < first:
        raise SSRError(f"--frames {text!r}: the range is reversed (last frame before first)")
    return first, last


def frame_numbers(scene, frames):
    if frames is None:
        return [scene.frame_current]
    return list(range(frames[0], frames[1] + 1))


def render_frame(scene, request, state=None):
    """Render the scene's current frame as REQUEST asks; returns (images, StageTimer).

    STATE (a ChainState) carries temporal history from the previous frame; a
    fresh one means a still, accumulated over `accumulate_frames` iterations.
    """
    timer = StageTimer()
    use_ssr = request.method == "ssr" and request.settings.use_ssr
    passes = render_passes(scene, request.engine, request.samples, request.resolution,
                           EEVEE_RAYTRACING_METHODS.get(request.method), split_lamp_specular=use_ssr)
    timer.lap("render")
    height, width = passes.depth.shape
    images = {"passes": passes, "final": passes.combined, "stats": {}}
    if not use_ssr:
        return images, timer
    ensure_backend()
    inputs = ChainInputs.from_passes(passes, request.settings)
    timer.lap("upload")
    outputs = run_chain(inputs, request.settings, state or ChainState(), timer)
    scale = 2 if request.settings.half_resolution else 1
    images.update(
        final=download(outputs.final_tx),
        reflection=download(outputs.reflection_tx),
        history_count=download(outputs.history_count_tx, 1)[..., 0] if outputs.history_count_tx else None,
        ray_hit=upsample_nearest(download(outputs.ray_hit_tx), scale, (height, width)),
        ray_dir=upsample_nearest(download(outputs.ray_dir_tx), scale, (height, width)),
        ray_stats=upsample_nearest(download(outputs.ray_stats_tx), scale, (height, width)))
    timer.lap("readback")
    ray_class = download(outputs.ray_stats_tx, 1)[..., 0]
    traced = np.count_nonzero(ray_class > 0)
    images["stats"] = {"iterations": outputs.iterations,
                       "expensive_ray_fraction": round(np.count_nonzero(ray_class == 2) / traced, 4)
                       if traced else 0.0}
    return images, timer


def upsample_nearest(array, scale, shape):
    """Full-resolution view of a traced-resolution buffer (image order): each texel covers its quad."""
    if scale == 1:
        return array
    bottom_up = array[::-1].repeat(scale, axis=0).repeat(scale, axis=1)[:shape[0], :shape[1]]
    return np.ascontiguousarray(bottom_up[::-1])


def pass_channels(images):
    """The channels of the passes EXR: the inputs, then the SSR intermediates (zero without SSR)."""
    passes = images["passes"]
    height, width = passes.depth.shape
    def intermediate(name, channels):
        value = images.get(name)
        return value if value is not None else np.zeros((height, width, channels), np.float32)
    reflection, ray_hit = intermediate("reflection", 4), intermediate("ray_hit", 4)
    ray_dir, ray_stats = intermediate("ray_dir", 4), intermediate("ray_stats", 4)
    history = images.get("history_count")
    channels = {}
    def layer(name, array, components):
        for index, component in enumerate(components):
            channels[f"{name}.{component}"] = array[..., index] if array.ndim == 3 else array
    layer("Combined", passes.combined, "RGBA")
    layer("Depth", passes.depth, "Z")
    layer("Normal", passes.normal, "XYZ")
    layer("Roughness", passes.roughness, "V")
    layer("Specular Color", passes.specular_color, "RGB")
    layer("Specular Direct", passes.specular_direct, "RGB")
    layer("Specular Indirect", passes.specular_indirect, "RGB")
    layer("SSR Reflection", reflection, "RGB")  # premultiplied by confidence: what FG multiplies
    layer("SSR Confidence", reflection[..., 3], "V")
    layer("SSR Hit", ray_hit, "UV")
    layer("SSR Ray PDF", ray_hit[..., 2], "V")
    layer("SSR Hit Distance", ray_dir[..., 3], "V")
    layer("SSR Ray Class", ray_stats[..., 0], "V")  # 0 none, 1 cheap (linear), 2 expensive (Hi-Z)
    layer("SSR HiZ Level", ray_stats[..., 2], "V")
    layer("SSR Iterations", ray_stats[..., 1], "V")
    # Share of each pixel that came from history: 1 - 1 / frames accumulated.
    layer("SSR History Weight", 1.0 - 1.0 / np.maximum(history, 1.0) if history is not None
          else np.zeros((height, width), np.float32), "V")
    return channels


def write_frame(out_dir, frame, images, scene):
    stem = os.path.join(out_dir, f"frame_{frame:04d}")
    final = images["final"]
    if not np.isfinite(final).all():
        raise SSRError(f"frame {frame}: the result has NaN or Inf pixels; nothing written")
    write_exr(stem + ".passes.exr", pass_channels(images))
    write_display_png(stem + ".png", final, scene)
    write_rgba_exr(stem + ".exr", final)
    return [os.path.basename(stem + suffix) for suffix in (".exr", ".png", ".passes.exr")]


def run_render(scene, scene_path, request, log=print):
    """Render every requested frame into request.out_dir and write report.json; returns the report."""
    require_camera(scene)
    frames = frame_numbers(scene, request.frames)
    prepare_output_folder(request.out_dir)
    report = {
        "scene": scene_path, "method": request.method, "engine": request.engine,
        "samples": request.samples, "settings": asdict(request.settings),
        "blender": bpy.app.version_string, "gpu": None, "frames": [],
    }
    state = ChainState()
    for frame in frames:
        scene.frame_set(frame)
        images, timer = render_frame(scene, request, state)
        write_frame(request.out_dir, frame, images, scene)
        timer.lap("write")
        if report["gpu"] is None and request.method == "ssr":
            report["gpu"] = describe_gpu()
        height, width = images["final"].shape[:2]
        report["resolution"] = [width, height]
        stages = {stage: round(ms, 3) for stage, ms in timer.milliseconds.items()}
        report["frames"].append({"frame": frame, "stages_ms": stages,
                                 "total_ms": round(sum(stages.values()), 3), **images["stats"]})
        write_json(os.path.join(request.out_dir, "report.json"), report)
        log(f"frame {frame}: {sum(stages.values()):.0f} ms "
            f"({', '.join(f'{k} {v:.0f}' for k, v in stages.items())})")
    return report
