"""`python -m ssr_addon preview SCENE --out DIR [--orbit N [--orbit-step DEGREES]]`: what the live viewport
shows, headless.

The scene camera's view is captured through the startup file's 3D View exactly as
the live mode captures the user's (viewport_capture), in Rendered shading with EEVEE,
then refined step by step as the live view refines a view that holds (progressive), until
it converges or reaches --iterations.
Writes preview.exr and preview.png (converged), first.png (the first image the live
view would show) and preview.json (timings: time to the first image, capture and
chain milliseconds per iteration; the capture's include the upload and any lamps-only draw,
the chain's the analytic lamp split and the pyramids).

With --orbit N the camera then orbits its target (the surface at the frame's centre) about
the vertical, --orbit-step degrees a view (default ORBIT_STEP_DEGREES), as an artist orbiting the
3D View: each view is
captured at one sample and shown after one iteration from the last view's history, as the
live view follows a moving view. Writes orbit/view_KK.exr per view as it is shown, and
orbit/view_KK.png for each once the orbit is done: a PNG goes through Blender's colour
management by way of the scene's image settings, which makes EEVEE's viewport sync the whole
scene at its next draw, a cost the live view does not pay between two updates (at 320x180 on
llvmpipe, 460-630 ms of a 1.7-2.3 s update). Each view's timings (capture, draws, chain) and the
updates per second go into preview.json.
"""
import math
import os
import time

import numpy as np

from ..blender.colour_management import write_display_png
from ..blender.gpu_context import ensure_backend
from ..blender.overrides import TemporaryChanges
from ..blender.render_setup import render_size, rendered_view_layer
from ..blender.scene_io import camera_matrices, require_camera
from ..blender.viewport_capture import ViewportCapture, headless_view3d
from ..core.gpu_backend import StageTimer, download
from ..core.inputs import BACKGROUND_DEPTH
from ..core.progressive import STEP_SECONDS, NavigatedViews
from .frame import FrameFallbacks, add_view_captures, decide_view_cube, keep_view_captures
from .outputs import prepare_output_folder, read_rgba_exr, write_json, write_rgba_exr, written_together

ORBIT_STEP_DEGREES = 1.0  # an artist orbiting: a few pixels of motion a view at the frame's centre
ORBIT_SAMPLES = 1         # viewport samples of an orbit view's capture, as the live view's while moving


def run_preview(scene, out_dir, settings, resolution=None, iterations=None, orbit=0, log=print, on_view=None,
                orbit_step=ORBIT_STEP_DEGREES, after_orbit=None):
    """Capture SCENE's camera view at RESOLUTION (default: the scene's) and refine it until it
    converges or has run ITERATIONS; then ORBIT views around it; write the images and timings into
    OUT_DIR; returns the timings. ON_VIEW(k, passes, ChainOutputs), if given, sees each orbit view
    (k from 1) as it is shown. AFTER_ORBIT(k, recapture), if given, is called for each orbit view once
    the orbit is done: recapture(samples) captures that view again at SAMPLES (None: the scene's).
    It waits for the orbit's end because a full-sample draw changes how EEVEE's viewport draws the
    next view at one sample: the orbit's views are drawn after one-sample draws only, as an
    artist's are."""
    camera = require_camera(scene)
    size = render_size(scene, resolution)
    prepare_output_folder(out_dir)
    space, region = headless_view3d()
    view_layer = rendered_view_layer(scene)
    view, projection = camera_matrices(scene, *size)
    clip = camera.data.clip_start, camera.data.clip_end
    ensure_backend()
    capture = ViewportCapture(space, region)
    fallbacks = FrameFallbacks(capture)

    def view_passes(view_matrix, samples=None, timer=None):
        """The passes of the view VIEW_MATRIX, its noisy passes at SAMPLES (None: the scene's
        viewport samples)."""
        return capture.capture(scene, view_layer, view_matrix, projection, size, clip, settings.lamp_split, timer,
                               samples)

    def capture_view(view_matrix, samples=None, timer=None):
        """view_passes with the captures the fallback asks for, drawn for that view."""
        passes = view_passes(view_matrix, samples, timer)
        add_view_captures(scene, view_layer, passes, settings, fallbacks, samples or scene.eevee.taa_samples, timer)
        return passes

    with TemporaryChanges() as changes:
        changes.set(scene.render, "engine", "BLENDER_EEVEE")
        changes.set(space.shading, "type", "RENDERED")
        started = time.perf_counter()
        capture_timer = StageTimer()
        try:
            passes = capture_view(view, timer=capture_timer)
            views = NavigatedViews(settings)
            refining = views.view(passes, inputs_timer=capture_timer, follow=False)
            first = download(refining.step()["final"])
            if decide_view_cube(scene, passes, refining.outputs, settings, fallbacks):
                add_view_captures(scene, view_layer, passes, settings, fallbacks, scene.eevee.taa_samples,
                                  capture_timer)
                refining = views.view(passes, inputs_timer=capture_timer, follow=False)
                first = download(refining.step()["final"])
            first_image_ms = (time.perf_counter() - started) * 1000.0
            while not refining.done and (iterations is None or refining.iterations < iterations):
                refining.step(STEP_SECONDS, None if iterations is None else iterations - refining.iterations)
            converged_ms = (time.perf_counter() - started) * 1000.0
            final = download(refining.outputs["final"])
            orbit_views = []
            if orbit:
                os.makedirs(os.path.join(out_dir, "orbit"), exist_ok=True)
                capture.hold_set_up(scene, view_layer, changes)
                orbit_matrices = orbit_view_matrices(view, target_distance(passes), orbit, orbit_step)
                for index, orbit_view in enumerate(orbit_matrices, 1):
                    orbit_views.append(_orbit_view(
                        capture, views, index, out_dir, on_view,
                        lambda timer, orbit_view=orbit_view: keep_view_captures(
                            view_passes(orbit_view, ORBIT_SAMPLES, timer), passes)))
                if after_orbit is not None:
                    for index, orbit_view in enumerate(orbit_matrices, 1):
                        after_orbit(index, lambda samples=None, orbit_view=orbit_view:
                                    capture_view(orbit_view, samples))
                for index in range(1, orbit + 1):
                    exr, png = _orbit_paths(out_dir, index)
                    with written_together([png]) as (partial,):
                        write_display_png(partial, read_rgba_exr(exr), scene)
        finally:
            fallbacks.release()
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
    if orbit_views:
        timings["orbit"] = orbit_views
        timings["orbit_updates_per_second"] = round(
            len(orbit_views) * 1000.0 / sum(view["time_to_image_ms"] for view in orbit_views), 3)
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
    if orbit_views:
        log(f"orbit: {len(orbit_views)} views, {timings['orbit_updates_per_second']:.2f} updates per second "
            f"({orbit_views[-1]['draws']} draws at {ORBIT_SAMPLES} sample each)")
    return timings


def _orbit_view(capture, views, index, out_dir, on_view, moving_passes):
    """Capture and show orbit view INDEX as the live view follows a moving view: MOVING_PASSES(timer)
    captures it as the live view does while moving; write its EXR and return its timings."""
    started = time.perf_counter()
    timer = StageTimer()
    draws = capture.draws
    passes = moving_passes(timer)
    following = views.view(passes, inputs_timer=timer)
    outputs = following.step(max_iterations=1)
    image = download(outputs["final"])
    time_to_image_ms = (time.perf_counter() - started) * 1000.0
    if on_view is not None:
        on_view(index, passes, outputs)
    with written_together(_orbit_paths(out_dir, index)[:1]) as (exr,):
        write_rgba_exr(exr, image)
    return {"view": index, "time_to_image_ms": round(time_to_image_ms, 1),
            "capture_ms": round(sum(timer.milliseconds.values()), 1), "draws": capture.draws - draws,
            "chain_ms": round(sum(following.timer.milliseconds.values()), 1),
            "history": following.state.sequence.has_history}


def _orbit_paths(out_dir, index):
    """(EXR, PNG) of orbit view INDEX."""
    return tuple(os.path.join(out_dir, "orbit", f"view_{index:02d}.{extension}") for extension in ("exr", "png"))


def target_distance(passes):
    """How far along the view axis the camera's target lies: the median depth of the surfaces in
    the middle fifth of the frame, or of all of them where the middle shows the world."""
    height, width = passes.depth.shape
    middle = passes.depth[2 * height // 5:3 * height // 5 + 1, 2 * width // 5:3 * width // 5 + 1]
    for depths in (middle, passes.depth):
        surface = depths[depths < BACKGROUND_DEPTH]
        if surface.size:
            return float(np.median(surface))
    return passes.clip_end * 0.5


def orbit_view_matrices(view_matrix, distance, count, step_degrees=ORBIT_STEP_DEGREES):
    """World-to-view matrices of COUNT views orbiting, STEP_DEGREES apart, about the vertical (world
    z) through the point DISTANCE ahead of the camera of VIEW_MATRIX, starting one step from it."""
    camera = np.linalg.inv(np.asarray(view_matrix, np.float64))
    target = camera @ np.array([0.0, 0.0, -distance, 1.0])
    to_target, from_target = np.eye(4), np.eye(4)
    to_target[:3, 3], from_target[:3, 3] = target[:3], -target[:3]
    matrices = []
    for step in range(1, count + 1):
        angle = math.radians(step_degrees * step)
        turn = np.eye(4)
        turn[:2, :2] = [[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]
        matrices.append(np.linalg.inv(to_target @ turn @ from_target @ camera).astype(np.float32))
    return matrices
