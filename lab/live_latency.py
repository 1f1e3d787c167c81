"""Live SSR latency: from a view change to the first SSR image and to convergence.

    python -m lab live [--resolutions WxH ...] [--page docs/measurements.md]

At each resolution the scene camera's view is previewed once to warm EEVEE's viewport
(shader compilation), then the camera moves a little and the view is previewed again,
exactly as the live mode captures and refines a view that has just stopped moving
(ssr_addon.batch.preview). The second preview's images (first image, converged) go to
IMAGES/WxH/ (IMAGES: --images, default docs/live) and its timings into the table.
"""
import os

import bpy
import gpu
import numpy as np

from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.batch.preview import run_preview
from ssr_addon.batch.request import parse_resolution
from ssr_addon.blender.colour_management import DisplayTransform
from ssr_addon.blender.gpu_context import ensure_backend
from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.gpu_backend import StageTimer, TexturePool, describe_gpu, download, upload
from ssr_addon.core.progressive import STEP_SECONDS, ProgressiveView
from ssr_addon.core.settings import ChainSettings
from ssr_addon.ui.live import draw_image
from .bench.scenes import REPO, resolve_scene
from .docs import page_link, require_page, rewrite_block

SCENE = "mirror_floor"
OUT = os.path.join(REPO, "docs", "live")


def measure(resolution, images):
    scene = load_scene(resolve_scene(SCENE))
    folder = os.path.join(images, "{}x{}".format(*resolution))
    run_preview(scene, folder, ChainSettings(), resolution, log=lambda line: None)  # warms the viewport engine
    scene.camera.location.x += 0.05  # the view changes, as after a navigation
    bpy.context.view_layer.update()
    timings = run_preview(scene, folder, ChainSettings(), resolution)
    timings["draw_ms"] = overlay_draw_ms(scene, timings["resolution"])
    return timings


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
    parser.add_argument("--resolutions", nargs="+", type=parse_resolution, default=[(320, 180), (1280, 720)])
    parser.add_argument("--page", help="rewrite a block of this markdown page with the table")
    parser.add_argument("--block", default="live", help="the block to rewrite (default: live)")
    parser.add_argument("--images", default=OUT, help="folder of the WxH/ image folders (default: docs/live)")
    arguments = parser.parse_args(argv)
    require_page(arguments.page)
    arguments.images = os.path.abspath(arguments.images)
    rows = [measure(resolution, arguments.images) for resolution in arguments.resolutions]
    ensure_backend()
    images = os.path.relpath(arguments.images, REPO).replace(os.sep, "/")
    lines = [f"Latest run: `python -m lab live"
             f"{' --page docs/measurements.md' if arguments.page else ''}"
             f"{f' --block {arguments.block}' if arguments.block != 'live' else ''}"
             f"{f' --images {images}' if images != 'docs/live' else ''}` on {describe_gpu()['renderer']}, "
             f"{SCENE}, balanced preset, after a camera move (EEVEE already compiled).", "",
             "| resolution | first SSR image | converged | iterations | capture (passes) | lamp split "
             "| chain per iteration | overlay draw | add-on share (chain + draw) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        capture = row["capture_ms"]
        # A lamps-only draw is part of the capture; the analytic split is the chain's first pass.
        lamp_split_ms = capture.get("lamp_split", 0.0) + row["chain_stages_ms"].get("lamp_split", 0.0)
        lines.append(f"| {row['resolution'][0]}x{row['resolution'][1]} | {row['time_to_first_image_ms'] / 1000:.2f} s "
                     f"| {row['time_to_last_image_ms'] / 1000:.2f} s | {row['iterations']} "
                     f"| {capture['capture']:.0f} ms | {lamp_split_ms:.0f} ms "
                     f"| {row['chain_ms_per_iteration']:.1f} ms | {row['draw_ms']:.2f} ms "
                     f"| {row['chain_ms_per_iteration'] + row['draw_ms']:.1f} ms |")
    first = arguments.resolutions[0]
    folder = page_link(arguments.page or os.path.join(REPO, "docs", "measurements.md"),
                       os.path.join(arguments.images, "{}x{}".format(*first))).replace(os.sep, "/")
    lines += ["", f"First image, then converged ({first[0]}x{first[1]}):", "",
              f"![first live image]({folder}/first.png) ![converged live image]({folder}/preview.png)"]
    text = "\n".join(lines)
    print(text)
    if arguments.page:
        rewrite_block(arguments.page, arguments.block, text, "Live SSR in the viewport")


def reflective_mask(passes):
    """The reflective pixels, as the bench counts them: smooth enough for SSR, visibly specular."""
    return (passes.roughness <= 0.5) & (passes.specular_color.mean(axis=-1) >= 0.1) & (passes.depth < 1e9)


def orbit_quality(scene, folder, settings, resolution, views):
    """Preview SCENE's camera view, then orbit it VIEWS views (preview --orbit); per orbit view, the
    error on the reflective pixels (relative L1) against a converged still of that view, of the
    moving view, of one iteration of its own one-sample passes without history and of EEVEE's image
    without SSR; and the orbit's
    flicker: the mean change, from one view to the next, of the moving view's difference from the
    converged still, relative to the reflective pixels' brightness (what changes that the stills
    do not change). Returns (timings, rows, flicker)."""
    rows, errors = [], []

    def measure(index, passes, outputs, recapture):
        moving = download(outputs["final"])[..., :3]
        alone = download(ProgressiveView(passes, settings).step(max_iterations=1)["final"])[..., :3]
        still_passes = recapture()
        still = ProgressiveView(still_passes, settings)
        while not still.done:
            still.step(STEP_SECONDS)
        reference = download(still.outputs["final"])[..., :3]
        mask = reflective_mask(still_passes)
        level = np.abs(reference[mask]).sum()
        rows.append({"view": index, "moving": float(np.abs(moving - reference)[mask].sum() / level),
                     "without_history": float(np.abs(alone - reference)[mask].sum() / level),
                     "without_ssr": float(np.abs(still_passes.combined[..., :3] - reference)[mask].sum() / level),
                     "still_iterations": still.iterations})
        errors.append((moving - reference, mask, float(reference[mask].mean())))

    timings = run_preview(scene, folder, settings, resolution, orbit=views, log=lambda line: None, on_view=measure)
    changes = [np.abs(after - before)[mask_before & mask_after].mean() / max(level, 1e-6)
               for (before, mask_before, level), (after, mask_after, _) in zip(errors, errors[1:])]
    return timings, rows, float(np.mean(changes)) if changes else None
