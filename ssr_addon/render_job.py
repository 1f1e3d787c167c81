"""Render frames of a scene with SSR, without SSR or with Cycles, and write them out.

Shared by the command line and the operators: everything here takes the
scene and a RenderRequest, never bpy.context.
"""
import ctypes
import ctypes.util
import os
import re
from dataclasses import dataclass, field

import bpy
import numpy as np

from .chain import ChainInputs, ChainState, run_chain
from .errors import SSRError
from .gpu_backend import StageTimer, describe_gpu, download, ensure_backend
from .outputs import (prepare_output_folder, write_display_png, write_exr, write_json, write_rgba_exr,
                      written_together)
from .params import ChainSettings
from .passes import (ENGINES, SSR_BASE_RAYTRACING, lamp_split_method, lamp_world_for_run, render_passes, render_samples,
                     render_size)
from .progress import FrameProgress
from .run_report import REPORT_NAME, claim_folder, fingerprint, frame_paths, scene_identity
from .scene_io import require_camera, require_square_pixels

# ssr: this project; none: the scene's own reflections (probes and the world, and EEVEE's
# screen tracing where the scene has ray tracing on); cycles: the path-traced reference;
# eevee-rt / eevee-rt-high: EEVEE's own screen-space ray tracing.
METHODS = ("ssr", "none", "cycles", "eevee-rt", "eevee-rt-high")
EEVEE_RAYTRACING_METHODS = {"eevee-rt": "default", "eevee-rt-high": "high"}  # methods that are EEVEE's own
# The EEVEE ray-tracing set-up (passes.EEVEE_RAYTRACING) each method renders with; "none" and
# the baselines render the scene's own.
RENDER_RAYTRACING = {**EEVEE_RAYTRACING_METHODS, "ssr": SSR_BASE_RAYTRACING}
# Frames re-rendered (not written) before the first missing frame of a resumed run, so
# its temporal history is as warm as an uninterrupted run's (the filter averages ~10).
# The frame sequence draws a frame's random numbers from its number alone, so the
# re-rendered frames trace the same rays as an uninterrupted run did.
RESUME_WARMUP_FRAMES = 8


@dataclass
class RenderRequest:
    out_dir: str
    method: str = "ssr"
    engine: str = "eevee"
    resolution: tuple = None     # (width, height) or the scene's own
    frames: tuple = None         # (first, last) inclusive, or the scene's current frame
    samples: int = None          # EEVEE TAA samples / Cycles samples; engine default if None
    settings: ChainSettings = field(default_factory=ChainSettings)
    on_error: str = "stop"       # a frame that fails: "stop" the run or "skip" to the next frame
    overwrite: bool = False      # replace the run in out_dir instead of resuming it (run_report)
    file_prefix: str = "frame_"  # frame N is written as {file_prefix}{N:04d}.exr, .png and .passes.exr
    mode: str = None             # the operators' comparison mode, when one applies a baseline
    time_stages: bool = False    # wait for the GPU after each chain stage to time it apart (benchmarks);
    #                              otherwise the GPU's work shows in "readback", and the frame is quicker

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
        lamp_split_method(self.engine, self.settings.lamp_split)  # one line now, not at the first frame
        if self.on_error not in ("stop", "skip"):
            raise SSRError(f"--on-error {self.on_error!r}: expected stop or skip")


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
    """The frames to render; a range must lie inside the scene's own frame range."""
    if frames is None:
        return [scene.frame_current]
    first, last = frames
    if first < scene.frame_start or last > scene.frame_end:
        raise SSRError(f"--frames {first}-{last} lies outside scene '{scene.name}' "
                       f"(frames {scene.frame_start}-{scene.frame_end})")
    return list(range(first, last + 1))


def render_frame(scene, request, state=None):
    """Render the scene's current frame as REQUEST asks; returns (images, StageTimer).

    STATE (a ChainState) carries temporal history from the previous frame; the
    caller has begun the frame in it (state.begin_frame). Without one the frame
    is a still, accumulated over `accumulate_frames` iterations.
    """
    timer = StageTimer(wait_for_gpu=request.time_stages)
    use_ssr = request.method == "ssr" and request.settings.use_ssr
    passes = render_passes(scene, request.engine, request.samples, request.resolution,
                           RENDER_RAYTRACING.get(request.method),
                           lamp_split=request.settings.lamp_split if use_ssr else "off", timer=timer)
    timer.lap("render")  # reading the passes back
    images = {"passes": passes, "final": passes.combined, "stats": {}}
    if not use_ssr:
        return images, timer
    ensure_backend()
    inputs = ChainInputs.from_passes(passes, request.settings, timer)
    if state is None:
        state = ChainState.still()
        state.begin_frame(scene.frame_current)
    outputs = run_chain(inputs, request.settings, state, timer)
    images.update(chain_images(passes, outputs, request.settings))
    if inputs.specular_direct_tx is not None:  # split on the GPU: read back only if written (pass_channels)
        images["specular_split_tx"] = (inputs.specular_direct_tx, inputs.specular_indirect_tx)
    timer.lap("readback")
    return images, timer


def chain_images(passes, outputs, settings):
    """The chain's ChainOutputs as full-resolution arrays by name (final, reflection, the
    intermediates and ray buffers, as pass_channels writes them) and their stats."""
    height, width = passes.depth.shape
    scale = 2 if settings.half_resolution else 1
    ray_stats = download(outputs.ray_stats_tx)
    ray_class = ray_stats[..., 0]  # one entry per traced ray, before upsampling
    traced = np.count_nonzero(ray_class > 0)
    return {
        "final": download(outputs.final_tx),
        "reflection": download(outputs.reflection_tx),
        "resolved": download(outputs.resolved_tx),
        "spatial": download(outputs.spatial_tx),
        "history_count": download(outputs.history_count_tx, 1)[..., 0] if outputs.history_count_tx else None,
        "ray_hit": upsample_nearest(download(outputs.ray_hit_tx), scale, (height, width)),
        "ray_dir": upsample_nearest(download(outputs.ray_dir_tx), scale, (height, width)),
        "ray_stats": upsample_nearest(ray_stats, scale, (height, width)),
        "stats": {"iterations": outputs.iterations,
                  "expensive_ray_fraction": round(np.count_nonzero(ray_class == 2) / traced, 4) if traced else 0.0},
    }


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
    resolved, spatial = intermediate("resolved", 4), intermediate("spatial", 4)
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
    layer("F0", passes.f0, "RGB")
    split_tx = images.get("specular_split_tx")
    layer("Specular Direct", download(split_tx[0], 3) if split_tx else passes.specular_direct, "RGB")
    layer("Specular Indirect", download(split_tx[1], 3) if split_tx else passes.specular_indirect, "RGB")
    layer("SSR Reflection", reflection, "RGB")  # premultiplied by confidence: what FG multiplies
    layer("SSR Confidence", reflection[..., 3], "V")
    # The stages before the temporal filter, last iteration: the resolve (firefly guard
    # included) and the spatial filter, each premultiplied radiance and confidence.
    layer("SSR Resolve", resolved, "RGBA")
    layer("SSR Spatial", spatial, "RGBA")
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


def write_frame(out_dir, frame, images, scene, prefix="frame_"):
    """Write one frame's three files under temporary names, then rename them together."""
    final = images["final"]
    if not np.isfinite(final).all():
        raise SSRError(f"frame {frame}: the result has NaN or Inf pixels; nothing written")
    final_exr, png, passes_exr = frame_paths(out_dir, prefix, frame)
    with written_together([passes_exr, png, final_exr]) as (passes_partial, png_partial, final_partial):
        write_exr(passes_partial, pass_channels(images))
        write_display_png(png_partial, final, scene)
        write_rgba_exr(final_partial, final)


def return_large_buffers_to_the_system():
    """Serve every allocation over 1 MiB with its own mapping (glibc), freed back at once.

    Each frame allocates and frees tens of full-resolution buffers; glibc's
    adaptive threshold otherwise moves them onto the heap after the first free,
    where fragmentation grows resident memory ~10 MiB a frame at 1600x900
    (benchmarks/batch_memory.py).
    """
    libc_name = ctypes.util.find_library("c")
    if libc_name and hasattr(ctypes.CDLL(libc_name), "mallopt"):
        m_mmap_threshold = -3
        ctypes.CDLL(libc_name).mallopt(m_mmap_threshold, 1 << 20)


class RenderRun:
    """One run of REQUEST over SCENE's frames into request.out_dir, carrying temporal history.

    Made before anything renders: it checks the scene and claims the output
    folder (run_report: resume a matching run, refuse a different one).
    `frames()` renders and writes the frames one at a time, yielding each
    (frame, images) once written, so a modal operator can step it; the report
    (also report.json, rewritten after every frame) is in `report`.
    RENDER(scene, request, state) renders one frame (default render_frame; an
    operator's applies a comparison baseline). UNSAVED_CHANGES: the scene file on
    disk is not what renders, so the run can never be resumed.
    """

    def __init__(self, scene, scene_path, request, log=print, progress_stream=None, render=None,
                 unsaved_changes=False):
        require_camera(scene)
        require_square_pixels(scene)
        self.scene, self.request, self.log, self.render = scene, request, log, render or render_frame
        self.progress_stream = progress_stream
        self.frame_list = frame_numbers(scene, request.frames)
        prepare_output_folder(request.out_dir)
        return_large_buffers_to_the_system()
        self.report_path = os.path.join(request.out_dir, REPORT_NAME)
        samples = render_samples(scene, request.engine, request.samples)
        identity = fingerprint(scene_identity(scene_path, unsaved_changes), request,
                               render_size(scene, request.resolution), samples)
        kept = claim_folder(request.out_dir, identity, self.frame_list, request.overwrite)
        self.todo = [f for f in self.frame_list if f not in kept]
        self.report = {
            "fingerprint": identity,
            "scene": scene_path, "method": request.method, "engine": request.engine, "samples": samples,
            "blender": bpy.app.version_string, "gpu": None,
            "frames": [entry for _, entry in sorted(kept.items())],
            "failed_frames": [],
        }

    def frames(self):
        request = self.request
        if not self.todo:
            self.log(f"all {len(self.frame_list)} frames are already complete in {request.out_dir}")
            return
        first_missing = self.todo[0]
        warmup = [f for f in self.frame_list if first_missing - RESUME_WARMUP_FRAMES <= f < first_missing] \
            if request.method == "ssr" and request.settings.use_temporal else []
        if len(self.todo) < len(self.frame_list):
            self.log(f"resuming at frame {first_missing}: {len(self.frame_list) - len(self.todo)} complete frames "
                     f"kept, history re-warmed over {len(warmup)} frames")
        # One frame is a still (accumulated until converged); a range is an animation whose
        # history carries from frame to frame, reset on a jump in the range or a camera cut.
        state = ChainState.still() if len(self.frame_list) == 1 else ChainState()
        with lamp_world_for_run():
            yield from self._render_frames(warmup, first_missing, state)
        _summarise(self.report, self.log)
        write_json(self.report_path, self.report)
        failed = self.report["failed_frames"]
        if failed:
            raise SSRError(f"{len(failed)} frame(s) failed: {', '.join(str(entry['frame']) for entry in failed)}")

    def _render_frames(self, warmup, first_missing, state):
        request, scene = self.request, self.scene
        warned = set()
        progress = None  # started at the first written frame, so warm-up does not skew the ETA
        for frame in warmup + self.todo:
            scene.frame_set(frame)
            state.begin_frame(frame, scene.camera.name if scene.camera else None)
            if frame == first_missing:
                progress = FrameProgress(len(self.todo), self.progress_stream)
            try:
                images, timer = self.render(scene, request, state)
                self._warn_once(images["passes"], warned)
                if frame in warmup:
                    continue
                write_frame(request.out_dir, frame, images, scene, request.file_prefix)
                timer.lap("write")
            except SSRError as error:
                if request.on_error == "stop" or frame in warmup:
                    raise
                self.log(f"frame {frame} failed: {error}; going on (--on-error skip)")
                self.report["failed_frames"].append({"frame": frame, "error": str(error)})
                state.reset_history()
                progress.frame_done(frame, "failed")
                write_json(self.report_path, self.report)
                continue
            self._record(frame, images, timer, progress)
            yield frame, images

    def _warn_once(self, passes, warned):
        """The material warnings of the passes, each logged once per run and kept in the report."""
        for warning in passes.material_warnings:
            if warning not in warned:
                warned.add(warning)
                self.log(f"warning: {warning}")
                self.report.setdefault("warnings", []).append(warning)

    def _record(self, frame, images, timer, progress):
        report = self.report
        if report["gpu"] is None and self.request.method == "ssr":
            report["gpu"] = describe_gpu()
        height, width = images["final"].shape[:2]
        report["resolution"] = [width, height]
        stages = {stage: round(ms, 3) for stage, ms in timer.milliseconds.items()}
        own_ms = sum(ms for stage, ms in stages.items() if stage != "render")
        report["frames"].append({"frame": frame, "stages_ms": stages, "total_ms": round(sum(stages.values()), 3),
                                 "render_ms": stages["render"], "addon_ms": round(own_ms, 3),
                                 **images["stats"]})
        report["frames"].sort(key=lambda entry: entry["frame"])
        write_json(self.report_path, report)
        progress.frame_done(frame, f"render {stages['render'] / 1000:.1f} s + add-on {own_ms / 1000:.2f} s")


def run_render(scene, scene_path, request, log=print, progress_stream=None):
    """Render every requested frame into request.out_dir (RenderRun); returns the report."""
    run = RenderRun(scene, scene_path, request, log, progress_stream)
    for _ in run.frames():
        pass
    return run.report


def _summarise(report, log):
    """The add-on's own cost per frame beside the render's, as a ratio (into the report and the log)."""
    timed = [entry for entry in report["frames"] if "addon_ms" in entry]
    if timed:
        render_ms = sum(entry["render_ms"] for entry in timed) / len(timed)
        addon_ms = sum(entry["addon_ms"] for entry in timed) / len(timed)
        report["mean_ms_per_frame"] = {"render": round(render_ms, 1), "addon": round(addon_ms, 1),
                                       "addon_over_render": round(addon_ms / render_ms, 4)}
        log(f"per frame: render {render_ms:.0f} ms, add-on (lamp split, read-back, chain, composite, writing) "
            f"{addon_ms:.0f} ms = {addon_ms / render_ms:.3f} x the render")
