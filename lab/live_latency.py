"""Live SSR latency: from a view change to the first SSR image and to convergence.

    python -m lab live [--resolutions WxH ...] [--orbit N] [--orbit-scenes NAME ...] [--page docs/measurements.md]

Each resolution is a 3D View's size; the live mode captures and traces it at --live-resolution
percent of it (default: the add-on's Live Resolution). At each, the scene camera's view is
previewed once to warm EEVEE's viewport (shader compilation), then the camera moves a little and
the view is previewed again, exactly as the live mode captures and refines a view that has just
stopped moving (ssr_addon.batch.preview). The second preview's timings go into the table; it
then orbits MOVING_VIEWS views (preview --orbit), whose updates are timed against one one-sample
viewport draw of Combined of the whole view (what EEVEE's own viewport draws when the view moves)
and at the captured size. The first resolution's images (first image, converged, and the orbit's
PNGs in orbit/) go to IMAGES/WxH/ (IMAGES: --images, default docs/live; WxH the view's size).
Then, at the first resolution, --orbit views around each of --orbit-scenes, each view measured
against a converged still of it (orbit_quality), and a slower orbit of each (FLICKER_ORBIT) for
its flicker.
"""
import os
import tempfile
import time

import bpy
import gpu
import numpy as np

from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.batch.preview import ORBIT_STEP_DEGREES, run_preview
from ssr_addon.batch.request import parse_resolution
from ssr_addon.blender.colour_management import DisplayTransform
from ssr_addon.blender.gpu_context import ensure_backend
from ssr_addon.blender.overrides import TemporaryChanges
from ssr_addon.blender.render_setup import rendered_view_layer
from ssr_addon.blender.scene_io import camera_matrices, load_scene
from ssr_addon.blender.viewport_capture import ViewportCapture, headless_view3d
from ssr_addon.core.gpu_backend import StageTimer, TexturePool, describe_gpu, download, upload
from ssr_addon.core.progressive import STEP_SECONDS, ProgressiveView, moving_view_settings
from ssr_addon.core.settings import ChainSettings
from ssr_addon.ui.live import draw_image
from ssr_addon.ui.live_session import live_capture_size
from ssr_addon.ui.properties import UI_PROPERTIES
from .bench.scenes import REPO, resolve_scene
from .bench.stability import FLICKER_LIMIT
from .docs import format_resolutions, page_link, require_page, rewrite_block

SCENE = "mirror_floor"
OUT = os.path.join(REPO, "docs", "live")
VIEW_SIZES = ((320, 180), (1280, 720))  # the 3D Views measured
MOVING_VIEWS = 6                      # orbit views the update while moving is timed over
# Views and degrees a view of the orbit whose flicker is measured: so slow that what is shown, and
# so an error that moves with it, moves less than a pixel a view at the captured size (at 1 degree
# a view the wet street's near corner moves about 7 pixels, most of it 1-2).
FLICKER_ORBIT = (12, 0.1)
ORBIT_SCENES = ("wet_street", "rolling_ball")
LIVE_RESOLUTION = UI_PROPERTIES["live_resolution"].keywords["default"]


def measure(view_size, live_resolution, images):
    """The timings of a view of VIEW_SIZE captured at LIVE_RESOLUTION percent of it."""
    scene = load_scene(resolve_scene(SCENE))
    folder = os.path.join(images, "{}x{}".format(*view_size))
    size = live_capture_size(view_size, live_resolution)
    run_preview(scene, folder, ChainSettings(), size, log=lambda line: None)  # warms the viewport engine
    scene.camera.location.x += 0.05  # the view changes, as after a navigation
    bpy.context.view_layer.update()
    timings = run_preview(scene, folder, ChainSettings(), size, orbit=MOVING_VIEWS)
    for name in os.listdir(os.path.join(folder, "orbit")):  # the moving views' PNGs are kept
        if name.endswith(".exr"):
            os.remove(os.path.join(folder, "orbit", name))
    timings["view_size"] = view_size
    timings["draw_ms"] = overlay_draw_ms(scene, view_size)
    timings["view_draw_ms"] = one_sample_draw_ms(scene, view_size)
    timings["one_sample_draw_ms"] = one_sample_draw_ms(scene, timings["resolution"])
    return timings


def one_sample_draw_ms(scene, size, repeats=3):
    """Median milliseconds of one one-sample viewport draw of Combined after a camera move: the
    yardstick of a moving view's update (EEVEE's own viewport answers a move in about that)."""
    space, region = headless_view3d()
    capture = ViewportCapture(space, region)
    view_layer = rendered_view_layer(scene)
    times = []
    with TemporaryChanges() as changes:
        changes.set(space.shading, "type", "RENDERED")
        try:
            for repeat in range(repeats + 1):  # the first draw after the change of shading warms up
                scene.camera.location.x += 0.01
                view_layer.update()
                view, projection = camera_matrices(scene, *size)
                started = time.perf_counter()
                capture.draw_passes(scene, view_layer, view, projection, size, {"Combined": ("COMBINED", 4, 1)})
                times.append((time.perf_counter() - started) * 1000.0)
        finally:
            capture.release()
    return float(np.median(times[1:]))


def overlay_draw_ms(scene, size, repeats=20):
    """Milliseconds the live overlay takes per image over a SIZE region: the scene's colour
    management (blender.colour_management) and the draw (ui.live.draw_image)."""
    image = upload(np.full((size[1], size[0], 4), 0.5, np.float32))
    display, pool = DisplayTransform(), TexturePool()
    offscreen = gpu.types.GPUOffScreen(*size, format="RGBA16F")
    try:
        with offscreen.bind():
            draw_image(display.apply(scene, image, pool), *size)  # compiles the shaders, bakes the LUT
            timer = StageTimer()
            for _ in range(repeats):
                draw_image(display.apply(scene, image, pool), *size)
            timer.lap("draw", offscreen.texture_color)
    finally:
        offscreen.free()
    return timer.milliseconds["draw"] / repeats


def main(argv):
    parser = ArgumentParser(prog="python -m lab live", description=__doc__.splitlines()[0])
    parser.add_argument("--resolutions", nargs="+", type=parse_resolution, default=list(VIEW_SIZES),
                        help=f"the views' sizes (default {format_resolutions(VIEW_SIZES)})")
    parser.add_argument("--live-resolution", type=int, default=LIVE_RESOLUTION, choices=range(10, 101),
                        metavar="PERCENT", help="the share of each view's size captured and traced "
                                                f"(Live Resolution; default {LIVE_RESOLUTION})")
    parser.add_argument("--orbit", type=int, default=24, help="views of the orbits measured against converged "
                                                            "stills at the first resolution (0: none; default 24)")
    parser.add_argument("--orbit-scenes", nargs="+", default=list(ORBIT_SCENES))
    parser.add_argument("--page", help="rewrite a block of this markdown page with the table")
    parser.add_argument("--block", default="live", help="the block to rewrite (default: live)")
    parser.add_argument("--images", default=OUT, help="folder of the WxH/ image folders (default: docs/live)")
    arguments = parser.parse_args(argv)
    require_page(arguments.page)
    arguments.images = os.path.abspath(arguments.images)
    with tempfile.TemporaryDirectory() as scratch:  # only the first view's images are shown
        rows = [measure(resolution, arguments.live_resolution, arguments.images if index == 0 else scratch)
                for index, resolution in enumerate(arguments.resolutions)]
    view, first = arguments.resolutions[0], rows[0]["resolution"]  # the first view's size and captured size
    with tempfile.TemporaryDirectory() as scratch:  # the orbits' own images are not shown
        orbits = [(name, *orbit_quality(load_scene(resolve_scene(name)), os.path.join(scratch, name),
                                        ChainSettings(), first, arguments.orbit)[:2],
                   orbit_quality(load_scene(resolve_scene(name)), os.path.join(scratch, f"{name}_slow"),
                                 ChainSettings(), first, *FLICKER_ORBIT)[2])
                  for name in (arguments.orbit_scenes if arguments.orbit else ())]
    ensure_backend()
    images = os.path.relpath(arguments.images, REPO).replace(os.sep, "/")
    lines = [f"Latest run: `python -m lab live"
             f"{f' --resolutions {format_resolutions(arguments.resolutions)}' if tuple(arguments.resolutions) != VIEW_SIZES else ''}"
             f"{f' --live-resolution {arguments.live_resolution}' if arguments.live_resolution != LIVE_RESOLUTION else ''}"
             f"{f' --orbit {arguments.orbit}' if arguments.orbit != 24 else ''}"
             f"{' --page docs/measurements.md' if arguments.page else ''}"
             f"{f' --block {arguments.block}' if arguments.block != 'live' else ''}"
             f"{f' --images {images}' if images != 'docs/live' else ''}` on {describe_gpu()['renderer']}, "
             f"{SCENE}, balanced preset, Live Resolution {arguments.live_resolution} %: a view of the first "
             "column's size is captured and traced at the second's. After a camera move (EEVEE already "
             f"compiled). While moving: the median of {MOVING_VIEWS} orbit views, each captured at one sample "
             "and shown after one iteration from the last view's history; against one one-sample viewport "
             "draw of Combined in the same run, of the whole view (what EEVEE's own viewport draws when the "
             "view moves) and at the captured size.", "",
             "| view | captured | moving: update | draws a update | EEVEE's one-sample draw of the view "
             "| update / that draw | one-sample draw, captured size | update / that draw | updates per s "
             "| held: first SSR image | converged | iterations | capture (passes) | captures past the screen "
             "| lamp split | chain per iteration | overlay draw |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        capture = row["capture_ms"]
        # A lamps-only draw is part of the capture; the analytic split is the chain's first pass.
        lamp_split_ms = capture.get("lamp_split", 0.0) + row["chain_stages_ms"].get("lamp_split", 0.0)
        # The held view's planar capture and cube map, drawn through the view; a moving view keeps them.
        beyond_ms = capture.get("planar_capture", 0.0) + capture.get("cube_capture", 0.0)
        update_ms = float(np.median([view["time_to_image_ms"] for view in row["orbit"]]))
        lines.append(f"| {row['view_size'][0]}x{row['view_size'][1]} | {row['resolution'][0]}x{row['resolution'][1]} "
                     f"| {update_ms:.0f} ms | {row['orbit'][-1]['draws']} at 1 sample | {row['view_draw_ms']:.0f} ms "
                     f"| {update_ms / row['view_draw_ms']:.1f}x | {row['one_sample_draw_ms']:.0f} ms "
                     f"| {update_ms / row['one_sample_draw_ms']:.1f}x | {row['orbit_updates_per_second']:.2f} "
                     f"| {row['time_to_first_image_ms'] / 1000:.2f} s "
                     f"| {row['time_to_last_image_ms'] / 1000:.2f} s | {row['iterations']} "
                     f"| {capture['capture']:.0f} ms | {beyond_ms:.0f} ms | {lamp_split_ms:.0f} ms "
                     f"| {row['chain_ms_per_iteration']:.1f} ms | {row['draw_ms']:.2f} ms |")
    if orbits:
        lines += ["", f"Orbits of {arguments.orbit} views, {ORBIT_STEP_DEGREES:g} degree each, of a {view[0]}x{view[1]} "
                  f"view captured at {first[0]}x{first[1]}: "
                  "relative error on the reflective pixels against a converged still of each view, of the "
                  "moving view, of one iteration of its own passes without history, and of EEVEE's image "
                  "without SSR. Flicker: over a slow orbit of the same view, "
                  f"{FLICKER_ORBIT[0]} views {FLICKER_ORBIT[1]:g} degree apart, the mean change of the "
                  "image's error from one view to the next, relative to the reflective pixels' brightness "
                  f"(limit {FLICKER_LIMIT}, the stability suite's for a still camera). EEVEE's image without "
                  "SSR does not flicker: what it scores is what the motion leaves in the measure.", "",
                  "| scene | moving, mean (max) | without history, mean | views no worse than without history "
                  "| without SSR, least | flicker, slow orbit: moving | without SSR | updates per s |",
                  "|---|---|---|---|---|---|---|---|"]
        for name, timings, views, flicker in orbits:
            moving = [view["moving"] for view in views]
            alone = [view["without_history"] for view in views]
            lines.append(f"| {name} | {np.mean(moving):.3f} ({max(moving):.3f}) | {np.mean(alone):.3f} "
                         f"| {sum(m <= a for m, a in zip(moving, alone))} of {len(views)} "
                         f"| {min(view['without_ssr'] for view in views):.3f} | {flicker['moving']:.4f} "
                         f"| {flicker['without_ssr']:.4f} "
                         f"| {timings['orbit_updates_per_second']:.2f} |")
    folder = page_link(arguments.page or os.path.join(REPO, "docs", "measurements.md"),
                       os.path.join(arguments.images, "{}x{}".format(*view))).replace(os.sep, "/")
    lines += ["", f"First image, then converged (a {view[0]}x{view[1]} view, captured at {first[0]}x{first[1]}):", "",
              f"![first live image]({folder}/first.png) ![converged live image]({folder}/preview.png)"]
    text = "\n".join(lines)
    print(text)
    if arguments.page:
        rewrite_block(arguments.page, arguments.block, text, "Live SSR in the viewport")


def reflective_mask(passes):
    """The reflective pixels, as the bench counts them: smooth enough for SSR, visibly specular."""
    return (passes.roughness <= 0.5) & (passes.specular_color.mean(axis=-1) >= 0.1) & (passes.depth < 1e9)


def orbit_quality(scene, folder, settings, resolution, views, step_degrees=ORBIT_STEP_DEGREES):
    """Preview SCENE's camera view, then orbit it VIEWS views STEP_DEGREES apart (preview --orbit,
    --orbit-step); per orbit view, the
    error on the reflective pixels (relative L1) against a converged still of that view, of the
    moving view, of one iteration of its own one-sample passes without history (traced as a moving
    view is: progressive.moving_view_settings) and of EEVEE's image without SSR; and the orbit's
    flicker of each of the three (orbit_flicker). The stills are captured once the orbit is done
    (run_preview's after_orbit), so that the moving views are drawn as an artist's are. Returns
    (timings, rows, {name: flicker}), the names "moving", "without_history" and "without_ssr"."""
    rows, errors, shown = [], [], {}

    def show(index, passes, outputs):
        alone = ProgressiveView(passes, moving_view_settings(settings)).step(max_iterations=1)
        shown[index] = {"moving": download(outputs["final"])[..., :3],
                        "without_history": download(alone["final"])[..., :3]}

    def measure(index, recapture):
        still_passes = recapture()
        still = ProgressiveView(still_passes, settings)
        while not still.done:
            still.step(STEP_SECONDS)
        reference = download(still.outputs["final"])[..., :3]
        mask = reflective_mask(still_passes)
        level = np.abs(reference[mask]).sum()
        images = {**shown.pop(index), "without_ssr": still_passes.combined[..., :3]}
        rows.append({"view": index, **{name: float(np.abs(image - reference)[mask].sum() / level)
                                       for name, image in images.items()},
                     "still_iterations": still.iterations})
        errors.append(({name: image - reference for name, image in images.items()}, mask,
                       float(reference[mask].mean())))

    timings = run_preview(scene, folder, settings, resolution, orbit=views, log=lambda line: None, on_view=show,
                          orbit_step=step_degrees, after_orbit=measure)
    return timings, rows, {name: orbit_flicker(errors, name) for name in ("moving", "without_history", "without_ssr")}


def orbit_flicker(errors, name):
    """The mean change, from one view to the next, of image NAME's difference from the converged
    still, relative to the reflective pixels' brightness: what changes that the stills do not
    change. ERRORS: per view ({name: difference}, reflective mask, brightness). It counts an
    error that moves with the view as much as one that flickers in place, so it means flicker on
    an orbit slow enough that errors move less than a pixel a view (FLICKER_ORBIT); there EEVEE's
    image without SSR, which does not flicker, scores what the motion left in it."""
    changes = [np.abs(after[name] - before[name])[mask_before & mask_after].mean() / max(level, 1e-6)
               for (before, mask_before, level), (after, mask_after, _) in zip(errors, errors[1:])]
    return float(np.mean(changes)) if changes else None
