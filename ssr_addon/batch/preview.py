"""`python -m ssr_addon preview SCENE --out DIR`: what the live viewport shows, headless.

The scene camera's view is captured through the startup file's 3D View exactly as
the live mode captures the user's (viewport_capture), in Rendered shading with EEVEE,
then refined step by step as the live view refines it (progressive), until it converges
or reaches --iterations.
Writes preview.exr and preview.png (converged), first.png (the first image the live
view would show) and preview.json (timings: time to the first image, capture and
chain milliseconds per iteration; the capture's include the upload and any lamps-only draw,
the chain's the analytic lamp split and the pyramids).
"""
import os
import time

from ..blender.colour_management import write_display_png
from ..blender.gpu_context import ensure_backend
from ..blender.overrides import TemporaryChanges
from ..blender.render_setup import render_size, rendered_view_layer
from ..blender.scene_io import camera_matrices, require_camera
from ..blender.viewport_capture import ViewportCapture, headless_view3d
from ..core.gpu_backend import StageTimer, download
from ..core.progressive import STEP_SECONDS, ProgressiveView
from .outputs import prepare_output_folder, write_json, write_rgba_exr, written_together


def run_preview(scene, out_dir, settings, resolution=None, iterations=None, log=print):
    """Capture SCENE's camera view at RESOLUTION (default: the scene's) and refine it until it
    converges or has run ITERATIONS; write the images and timings into OUT_DIR; returns the timings."""
    camera = require_camera(scene)
    size = render_size(scene, resolution)
    prepare_output_folder(out_dir)
    space, region = headless_view3d()
    view_layer = rendered_view_layer(scene)
    view, projection = camera_matrices(scene, *size)
    ensure_backend()
    capture = ViewportCapture(space, region)
    with TemporaryChanges() as changes:
        changes.set(scene.render, "engine", "BLENDER_EEVEE")
        changes.set(space.shading, "type", "RENDERED")
        started = time.perf_counter()
        capture_timer = StageTimer()
        try:
            passes = capture.capture(scene, view_layer, view, projection, size,
                                     (camera.data.clip_start, camera.data.clip_end), settings.lamp_split,
                                     capture_timer)
        finally:
            capture.release()
    refining = ProgressiveView(passes, settings, inputs_timer=capture_timer)
    first = download(refining.step()["final"])
    first_image_ms = (time.perf_counter() - started) * 1000.0
    while not refining.done and (iterations is None or refining.iterations < iterations):
        refining.step(STEP_SECONDS, None if iterations is None else iterations - refining.iterations)
    converged_ms = (time.perf_counter() - started) * 1000.0
    final = download(refining.outputs["final"])
    chain_ms = sum(refining.timer.milliseconds.values())
    timings = {
        "resolution": list(size),
        "iterations": refining.iterations,
        "converged": refining.done,
        "time_to_first_image_ms": round(first_image_ms, 1),
        "time_to_last_image_ms": round(converged_ms, 1),
        "capture_ms": {stage: round(ms, 1) for stage, ms in capture_timer.milliseconds.items()},
        "chain_ms_per_iteration": round(chain_ms / refining.iterations, 2),
        "chain_stages_ms": {stage: round(ms, 2) for stage, ms in refining.timer.milliseconds.items()},
        "material_warnings": list(passes.material_warnings),
    }
    paths = [os.path.join(out_dir, name) for name in ("preview.exr", "preview.png", "first.png")]
    with written_together(paths) as (exr, png, first_png):
        write_rgba_exr(exr, final)
        write_display_png(png, final, scene)
        write_display_png(first_png, first, scene)
    write_json(os.path.join(out_dir, "preview.json"), timings)
    log(f"preview: first image {first_image_ms / 1000:.2f} s, {refining.iterations} iterations "
        f"({'converged' if refining.done else 'not converged'}) in {converged_ms / 1000:.2f} s; "
        f"capture {sum(capture_timer.milliseconds.values()):.0f} ms, "
        f"chain {timings['chain_ms_per_iteration']:.1f} ms per iteration")
    return timings
