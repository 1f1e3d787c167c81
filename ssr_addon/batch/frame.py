"""One frame: its passes rendered as a RenderRequest asks, the chain run over them where the
method is SSR, its layers read back (FrameImages), and its three files written together.

Shared by the command line and the operators: everything here takes the scene and a
RenderRequest, never bpy.context.
"""
from dataclasses import dataclass

import numpy as np

from ..blender.colour_management import write_display_png
from ..blender.gpu_context import ensure_backend
from ..blender.planar_capture import PlanarCaptures
from ..blender.render_passes import render_passes
from ..blender.render_setup import decide_render
from ..blender.viewport_capture import headless_viewport
from ..core.chain import ChainState, run_chain
from ..core.errors import SSRError
from ..core.gpu_backend import StageTimer, download
from ..core.inputs import ChainInputs
from ..core.layers import exr_channels, read_layers
from .outputs import write_exr, write_rgba_exr, written_together
from .request import RENDER_RAYTRACING
from .run_report import frame_paths


@dataclass
class FrameImages:
    """What one frame rendered: its PASSES (RenderPasses), the FINAL image (H, W, 4), every
    layer of its passes EXR by name (core.layers) and STATS of the chain's work."""
    passes: object
    final: np.ndarray
    layers: dict
    stats: dict


def render_frame(scene, request, state=None, captures=None):
    """Render the scene's current frame as REQUEST asks; returns (FrameImages, StageTimer).

    STATE (a ChainState) carries temporal history from the previous frame; the
    caller has begun the frame in it (state.begin_frame). Without one the frame
    is a still, accumulated over `accumulate_iterations` iterations. CAPTURES
    (blender.planar_capture.PlanarCaptures) draws the planar capture and keeps it
    for the next frame; without one a capture is drawn for this frame alone.
    """
    timer = StageTimer(wait_for_gpu=request.time_stages)
    use_ssr = request.method == "ssr" and request.settings.use_ssr
    settings = request.settings
    setup = decide_render(scene, request.engine, request.samples, request.resolution,
                          RENDER_RAYTRACING.get(request.method), lamp_split=settings.lamp_split if use_ssr else "off",
                          fallback=settings.fallback if use_ssr else "off", max_roughness=settings.max_roughness)
    if setup.lamp_split.method == "analytic":
        timer.lap("lamp_split")  # reading the scene's lights; the chain adds its pass
    own_captures = captures is None and setup.planar_capture != "off"
    if own_captures:
        captures = PlanarCaptures(headless_viewport())
    try:
        passes = render_passes(scene, setup, timer, captures)
    finally:
        if own_captures:
            captures.release()
    timer.lap("render")  # reading the passes back
    if not use_ssr:
        return FrameImages(passes, passes.combined, read_layers(passes), {}), timer
    ensure_backend()
    inputs = ChainInputs.from_passes(passes, request.settings, timer)
    if state is None:
        state = ChainState.still()
        state.begin_frame(scene.frame_current)
    outputs = run_chain(inputs, request.settings, state, timer)
    images = FrameImages(passes, download(outputs["final"]), read_layers(passes, outputs),
                         chain_stats(outputs))
    timer.lap("readback")
    return images, timer


def chain_stats(outputs):
    """The chain's work in a frame: iterations, rays traced in the last one, and the share of
    them that were expensive (Hi-Z)."""
    ray_class = download(outputs["ray_stats"])[..., 0]  # one entry per traced ray
    traced = np.count_nonzero(ray_class > 0)
    return {"iterations": outputs.iterations, "traced_rays": traced,
            "expensive_ray_fraction": round(np.count_nonzero(ray_class == 2) / traced, 4) if traced else 0.0}


def write_frame(out_dir, frame, images, scene, prefix="frame_"):
    """Write one frame's three files under temporary names, then rename them together."""
    final = images.final
    if not np.isfinite(final).all():
        raise SSRError(f"frame {frame}: the result has NaN or Inf pixels; nothing written")
    final_exr, png, passes_exr = frame_paths(out_dir, prefix, frame)
    with written_together([passes_exr, png, final_exr]) as (passes_partial, png_partial, final_partial):
        write_exr(passes_partial, exr_channels(images.layers))
        write_display_png(png_partial, final, scene)
        write_rgba_exr(final_partial, final)
