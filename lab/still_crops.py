"""Balanced stills at 1280x720 beside EEVEE's own ray tracing: crops at 2x, for the eye.

    python -m lab crops [--scenes NAME ...] [--page docs/measurements.md]

Renders each scene as a still with `ssr balanced` and with `eevee-rt` (EEVEE's
screen-space ray tracing at its defaults), crops the part where the
reflections are, and writes docs/crops/<scene>.png; with --page, rewrites
the page's crops block. Speckle and stair-steps show at this size, where
the 160x90 bench cannot show them.
"""
import os
import tempfile
import time

from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.batch.frame import render_frame
from ssr_addon.batch.request import RenderRequest
from ssr_addon.blender.scene_io import load_scene
from .bench import display
from .bench.charts import load_pyplot
from .bench.scenes import REPO, resolve_scene
from .docs import MEASUREMENTS, page_link, require_page, rewrite_block

RESOLUTION = (1280, 720)
CROP_SIZE = (320, 180)
# Left, top corner of each scene's crop as a share of the image: where its reflections are.
CROP_CORNERS = {"mirror_floor": (0.375, 0.55), "wet_street": (0.375, 0.48), "glossy_corridor": (0.25, 0.6)}
CONTENDERS = (("ssr balanced", "ssr"), ("EEVEE ray tracing", "eevee-rt"))
OUT = os.path.join(REPO, "docs", "crops")


def crop(image, scene_name):
    left, top = CROP_CORNERS[scene_name]
    x, y = int(left * image.shape[1]), int(top * image.shape[0])
    return image[y:y + CROP_SIZE[1], x:x + CROP_SIZE[0], :3]


def render_crops(scene_name, folder):
    scene = load_scene(resolve_scene(scene_name))
    crops, seconds = {}, {}
    for label, method in CONTENDERS:
        started = time.perf_counter()
        images, _ = render_frame(scene, RenderRequest(out_dir=folder, method=method, resolution=RESOLUTION))
        seconds[label] = time.perf_counter() - started
        crops[label] = crop(images.final, scene_name)
    return crops, seconds


def write_sheet(scene_name, crops):
    plt = load_pyplot()
    figure, axes = plt.subplots(1, len(crops), figsize=(6.4 * len(crops), 3.9), dpi=100)
    for axis, (label, image) in zip(axes, crops.items()):
        axis.imshow(display(image), interpolation="nearest")
        axis.set_title(label)
        axis.axis("off")
    figure.tight_layout()
    path = os.path.join(OUT, f"{scene_name}.png")
    figure.savefig(path)
    plt.close(figure)
    return path


def main(argv):
    parser = ArgumentParser(prog="python -m lab crops", description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["mirror_floor", "wet_street"], choices=sorted(CROP_CORNERS))
    parser.add_argument("--page", help="rewrite the crops block of this markdown page")
    arguments = parser.parse_args(argv)
    require_page(arguments.page)
    os.makedirs(OUT, exist_ok=True)
    lines = [f"Latest run: `python -m lab crops --scenes {' '.join(arguments.scenes)} "
             f"--page docs/measurements.md`: stills at {RESOLUTION[0]}x{RESOLUTION[1]}, EEVEE at the add-on's samples, "
             f"{CROP_SIZE[0]}x{CROP_SIZE[1]} crops shown at 2x.", ""]
    with tempfile.TemporaryDirectory(prefix="ssr_crops_") as folder:
        for scene_name in arguments.scenes:
            crops, seconds = render_crops(scene_name, folder)
            path = write_sheet(scene_name, crops)
            timing = ", ".join(f"{label} {value:.0f} s" for label, value in seconds.items())
            print(f"{scene_name}: {path} ({timing})")
            lines += [f"![{scene_name}]({page_link(arguments.page or MEASUREMENTS, path)})", "",
                      f"*{scene_name}* (render and chain on this machine: {timing})", ""]
    if arguments.page:
        rewrite_block(arguments.page, "crops", "\n".join(lines).rstrip(), "Stills beside EEVEE")
