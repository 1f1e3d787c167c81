"""`python -m lab demo SCENE DIR`: the end of `make demo`, the scene rendered with SSR off
(DIR/none) and on (DIR/ssr) side by side in DIR/side_by_side.png, through the scene's colour
management, each labelled with its FLIP against Cycles on the reflective pixels where the bench
has that reference cached (it caches every reference it renders, at the size it renders)."""
import os

from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.batch.run_report import REPORT_NAME, read_report
from ssr_addon.blender.colour_management import write_display_png
from ssr_addon.blender.comparison_sheet import comparison_sheet
from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.errors import SSRError
from .bench import DEFAULT_CACHE, REFERENCE_SAMPLES, flip_error, layer_rgb, read_channels
from .bench.references import cached_reference

SIDES = (("none", "SSR off"), ("ssr", "SSR on"))


def main(argv):
    parser = ArgumentParser(prog="python -m lab demo", description=__doc__.splitlines()[0])
    parser.add_argument("scene", help="the scene both folders rendered")
    parser.add_argument("out", help="the folder holding none/ and ssr/")
    parser.add_argument("--cache", default=DEFAULT_CACHE, help="folder of the bench's cached references")
    parser.add_argument("--reference-samples", type=int, default=REFERENCE_SAMPLES,
                        help="Cycles samples of the reference to look for")
    arguments = parser.parse_args(argv)
    finals = {}
    for folder, _ in SIDES:
        path = os.path.join(arguments.out, folder, "frame_0001.exr")
        if not os.path.isfile(path) or not read_report(os.path.dirname(path)):
            raise SSRError(f"{path} (or its {REPORT_NAME}) is missing: render the demo first (make demo)")
        finals[folder] = read_channels(path)
    scene = load_scene(arguments.scene)
    images = {folder: layer_rgb(channels, components="RGBA") for folder, channels in finals.items()}
    height, width = images["ssr"].shape[:2]
    reference = cached_reference(arguments.scene, (width, height), arguments.reference_samples, scene.frame_current,
                                 arguments.cache)
    tiles = []
    for folder, label in SIDES:
        lines = [label] if reference is None else \
            [label, f"FLIP {flip_error(reference.image, images[folder][..., :3], reference.mask):.3f} vs Cycles"]
        tiles.append((lines, images[folder]))
    path = os.path.join(arguments.out, "side_by_side.png")
    write_display_png(path, comparison_sheet(tiles), scene)
    note = "" if reference is not None else \
        f" (no Cycles reference of this scene at {width}x{height} in the bench's cache, {arguments.cache})"
    print(f"SSR off | on, side by side: {path}{note}")
    return path
