"""Balanced stills at 1280x720 beside EEVEE's own ray tracing: crops at 2x, for the eye.

    .venv/bin/python benchmarks/still_crops.py [--scenes NAME ...] [--readme README.md]

Renders each scene as a still with `ssr balanced` and with `eevee-rt` (EEVEE's
screen-space ray tracing at its defaults), crops the part where the
reflections are, and writes docs/crops/<scene>.png; with --readme, rewrites
the README's crops block. Speckle and stair-steps show at this size, where
the 160x90 bench cannot show them.
"""
import argparse
import os
import tempfile
import time

from common import REPO

from ssr_addon.bench import display
from ssr_addon.outputs import rewrite_readme_block
from ssr_addon.render_job import RenderRequest, render_frame
from ssr_addon.scene_io import load_scene

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
    scene = load_scene(os.path.join(REPO, "test_scenes", f"{scene_name}.py"))
    crops, seconds = {}, {}
    for label, method in CONTENDERS:
        started = time.perf_counter()
        images, _ = render_frame(scene, RenderRequest(out_dir=folder, method=method, resolution=RESOLUTION))
        seconds[label] = time.perf_counter() - started
        crops[label] = crop(images["final"], scene_name)
    return crops, seconds


def write_sheet(scene_name, crops):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
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


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["mirror_floor", "wet_street"], choices=sorted(CROP_CORNERS))
    parser.add_argument("--readme", help="rewrite the crops block of this README")
    arguments = parser.parse_args()
    os.makedirs(OUT, exist_ok=True)
    lines = [f"Latest run: `.venv/bin/python benchmarks/still_crops.py --scenes {' '.join(arguments.scenes)} "
             f"--readme README.md`: stills at {RESOLUTION[0]}x{RESOLUTION[1]}, EEVEE at the add-on's samples, "
             f"{CROP_SIZE[0]}x{CROP_SIZE[1]} crops shown at 2x.", ""]
    with tempfile.TemporaryDirectory(prefix="ssr_crops_") as folder:
        for scene_name in arguments.scenes:
            crops, seconds = render_crops(scene_name, folder)
            path = write_sheet(scene_name, crops)
            timing = ", ".join(f"{label} {value:.0f} s" for label, value in seconds.items())
            print(f"{scene_name}: {path} ({timing})")
            lines += [f"![{scene_name}](docs/crops/{scene_name}.png)", "",
                      f"*{scene_name}* (render and chain on this machine: {timing})", ""]
    if arguments.readme:
        rewrite_readme_block(arguments.readme, "crops", "\n".join(lines).rstrip(), "Stills beside EEVEE")


if __name__ == "__main__":
    main()
