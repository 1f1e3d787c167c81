"""What lamp_split=analytic and unshadowed cost and how far they are from the exact split (lamp_split=render).

    python -m lab lamps [--scenes NAME ...] [--resolution WxH] [--page docs/measurements.md]

For each scene one still is rendered through the whole chain once with each split, from the
same samples and rays. Errors are relative mean absolute differences on the reflective pixels (the
bench's mask): of the lamp highlights split off (Specular Direct) and of the final image. Times are
the split's own cost (a render, or the chain's analytic lamp pass, waited for), the fastest of two
frames.
"""
from dataclasses import replace

from ssr_addon.batch.frame import render_frame
from ssr_addon.batch.request import RenderRequest
from ssr_addon.blender.lamp_renders import lamp_world_for_run
from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.gpu_backend import describe_gpu
from ssr_addon.core.settings import ChainSettings
from .bench.metrics import reflective_mask, relative_mae
from .bench.scenes import resolve_scene, scene_label
from .docs import require_page, rewrite_block, scenes_parser

SCENES = ("mirror_floor", "rough_spheres", "curved_mirror", "rolling_ball", "wet_street", "emissive_panel",
          "crossed_shadows")
SPLITS = ("render", "unshadowed", "analytic")
APPROXIMATE = SPLITS[1:]
GOAL = 0.02  # the Cost issue's bound on the split's error, relative, on reflective pixels


def measure(scene_name, resolution):
    scene = load_scene(resolve_scene(scene_name))
    results = {}
    with lamp_world_for_run():
        for split in SPLITS:
            request = RenderRequest(out_dir="", resolution=resolution, samples=16, time_stages=True,
                                    settings=replace(ChainSettings(), lamp_split=split))
            times = []
            for _ in range(2):
                images, timer = render_frame(scene, request)
                times.append(timer.milliseconds.get("lamp_split", 0.0))
            results[split] = (images, min(times))
    exact, _ = results["render"]
    passes = exact.passes
    mask = reflective_mask(passes.roughness, passes.specular_color)
    row = {"scene": scene_label(resolve_scene(scene_name)), "ms": {split: results[split][1] for split in SPLITS}}
    for split in APPROXIMATE:
        approximate, _ = results[split]
        row[split] = (relative_mae(exact.layers["Specular Direct"], approximate.layers["Specular Direct"], mask),
                      relative_mae(exact.final[..., :3], approximate.final[..., :3], mask))
    return row


def _percent(value, digits):
    return "-" if value is None else f"{value:.{digits}%}"


def main(argv):
    arguments = scenes_parser("lamps", __doc__, SCENES, (160, 90), "lamp-split").parse_args(argv)
    require_page(arguments.page)
    rows = [measure(name, arguments.resolution) for name in arguments.scenes]
    width, height = arguments.resolution
    lines = [f"Latest run: `python -m lab lamps --resolution {width}x{height}"
             f"{' --page docs/measurements.md' if arguments.page else ''}` on {describe_gpu()['renderer']} "
             f"(scenes: {', '.join(arguments.scenes)}); "
             f"EEVEE at 16 samples. Error: relative mean absolute difference from `lamp_split=render` on the "
             f"reflective pixels (goal: at most {GOAL:.0%}).", "",
             "| scene | " + " | ".join(f"{split} ms" for split in SPLITS) + " | "
             + " | ".join(f"{split}: lamp highlights error | {split}: final image error" for split in APPROXIMATE)
             + " |",
             "|---" * (1 + len(SPLITS) + 2 * len(APPROXIMATE)) + "|"]
    for row in rows:
        cells = [f"{row['ms'][split]:.1f}" for split in SPLITS]
        for split in APPROXIMATE:
            lamp, final = row[split]
            cells += [_percent(lamp, 2), _percent(final, 3)]
        lines.append(f"| {row['scene']} | " + " | ".join(cells) + " |")
    text = "\n".join(lines)
    print(text)
    if arguments.page:
        rewrite_block(arguments.page, "lamps", text, "Lamp highlights")
