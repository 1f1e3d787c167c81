"""Live SSR latency: from a view change to the first SSR image and to convergence.

    .venv/bin/python benchmarks/live_latency.py [--resolutions WxH ...] [--readme README.md]

At each resolution the scene camera's view is previewed once to warm EEVEE's viewport
(shader compilation), then the camera moves a little and the view is previewed again,
exactly as the live mode captures and refines a view that has just stopped moving
(ssr_addon.preview). The second preview's images (first image, converged) go to
IMAGES/WxH/ (IMAGES: --images, default docs/live) and its timings into the table.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import bpy  # noqa: E402
import gpu  # noqa: E402
import numpy as np  # noqa: E402

from ssr_addon.display_lut import DisplayTransform  # noqa: E402
from ssr_addon.gpu_backend import StageTimer, TexturePool, describe_gpu, ensure_backend, upload  # noqa: E402
from ssr_addon.outputs import rewrite_readme_block  # noqa: E402
from ssr_addon.params import ChainSettings  # noqa: E402
from ssr_addon.preview import run_preview  # noqa: E402
from ssr_addon.render_job import parse_resolution  # noqa: E402
from ssr_addon.scene_io import load_scene  # noqa: E402
from ssr_addon.ui.live import draw_image  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = "mirror_floor"
OUT = os.path.join(REPO, "docs", "live")


def measure(resolution, images):
    scene = load_scene(os.path.join(REPO, "test_scenes", f"{SCENE}.py"))
    folder = os.path.join(images, "{}x{}".format(*resolution))
    run_preview(scene, folder, ChainSettings(), resolution, log=lambda line: None)  # warms the viewport engine
    scene.camera.location.x += 0.05  # the view changes, as after a navigation
    bpy.context.view_layer.update()
    timings = run_preview(scene, folder, ChainSettings(), resolution)
    timings["draw_ms"] = overlay_draw_ms(scene, timings["resolution"])
    return timings


def overlay_draw_ms(scene, size, repeats=20):
    """Milliseconds the live overlay takes per image over a SIZE region: the scene's colour
    management (display_lut) and the draw (ui.live.draw_image)."""
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


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolutions", nargs="+", type=parse_resolution, default=[(320, 180), (1280, 720)])
    parser.add_argument("--readme", help="rewrite a block of this README with the table")
    parser.add_argument("--block", default="live", help="the README block to rewrite (default: live)")
    parser.add_argument("--images", default=OUT, help="folder of the WxH/ image folders (default: docs/live)")
    arguments = parser.parse_args()
    arguments.images = os.path.abspath(arguments.images)
    rows = [measure(resolution, arguments.images) for resolution in arguments.resolutions]
    ensure_backend()
    images = os.path.relpath(arguments.images, REPO).replace(os.sep, "/")
    lines = [f"Latest run: `.venv/bin/python benchmarks/live_latency.py"
             f"{' --readme README.md' if arguments.readme else ''}"
             f"{f' --block {arguments.block}' if arguments.block != 'live' else ''}"
             f"{f' --images {images}' if images != 'docs/live' else ''}` on {describe_gpu()['renderer']}, "
             f"{SCENE}, balanced preset, after a camera move (EEVEE already compiled).", "",
             "| resolution | first SSR image | converged | iterations | capture (passes) | capture (lamp split) "
             "| chain per iteration | overlay draw | add-on share (chain + draw) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        capture = row["capture_ms"]
        lines.append(f"| {row['resolution'][0]}x{row['resolution'][1]} | {row['time_to_first_image_ms'] / 1000:.2f} s "
                     f"| {row['time_to_last_image_ms'] / 1000:.2f} s | {row['iterations']} "
                     f"| {capture['capture']:.0f} ms | {capture.get('lamp_split', 0.0):.0f} ms "
                     f"| {row['chain_ms_per_iteration']:.1f} ms | {row['draw_ms']:.2f} ms "
                     f"| {row['chain_ms_per_iteration'] + row['draw_ms']:.1f} ms |")
    first = arguments.resolutions[0]
    folder = os.path.relpath(os.path.join(arguments.images, "{}x{}".format(*first)), REPO).replace(os.sep, "/")
    lines += ["", f"First image, then converged ({first[0]}x{first[1]}):", "",
              f"![first live image]({folder}/first.png) ![converged live image]({folder}/preview.png)"]
    text = "\n".join(lines)
    print(text)
    if arguments.readme:
        rewrite_readme_block(arguments.readme, arguments.block, text, "Live SSR in the viewport")


if __name__ == "__main__":
    main()
