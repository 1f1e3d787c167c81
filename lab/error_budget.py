"""Where the error of `ssr balanced` comes from: the chain, EEVEE's frame, or screen space itself.

    python -m lab error-budget [--scenes NAME ...] [--frame N] [--resolution WxH] [--page docs/measurements.md]

For each bench scene, a still of the frame the bench scores (`make bench`: frame 8), FLIP on the reflective
pixels against the bench's cached Cycles reference, beside EEVEE's ray tracing:
- eevee-rt-planar: EEVEE's ray tracing with its own plane probe on the scene's main reflector
  (scenes with a flat mesh);
- ours: the balanced chain over EEVEE's passes, as the bench renders it (fallback=auto);
- ours, screen alone: the same with fallback=off, screen space and nothing past it;
- ours, Cycles captures: ours with capture_engine=cycles (the captures lit with indirect light);
- correct screen space: EEVEE's frame with the reflection a correct screen-space method
  would show (lab.ideal_reflection: exact rays, EEVEE's Combined where the
  camera sees their hits, EEVEE's probe/world reflection elsewhere). No screen-space
  reflection over EEVEE's frame does better, but by errors that cancel EEVEE's;
- perfect fallback: ours, screen alone, with Cycles' reflection wherever its rays missed
  (1 - confidence): the ceiling of any fallback hierarchy after our screen trace;
- correct reflections: EEVEE's frame with Cycles' own reflections in place of EEVEE's
  probe/world reflection: what a perfect reflection method would reach over EEVEE's lighting;
- ours on Cycles' passes: the same chain over a Cycles render (its lighting, no EEVEE in it).
The "Right before new" issue's goal is a ratio to EEVEE's ray tracing of at most 0.8.
"""
from dataclasses import replace

import numpy as np

from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.batch.frame import render_frame
from ssr_addon.batch.request import RenderRequest, parse_resolution
from ssr_addon.blender.baselines import apply_baseline
from ssr_addon.blender.lamp_renders import lamp_world_for_run
from ssr_addon.blender.overrides import TemporaryChanges
from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.errors import SSRError
from ssr_addon.core.settings import ChainSettings
from .bench import DEFAULT_CACHE, DEFAULT_SCENES, EEVEE_SAMPLES, REFERENCE_SAMPLES, flip_error, render_reference
from .bench.scenes import resolve_scene
from .docs import require_page, rewrite_block
from .ideal_reflection import ideal_screen_space, with_reflection

GOAL = 0.8
CYCLES_SAMPLES = 512
CYCLES_SEED = 7  # not one of the reference's seeds, so its noise is not the reference's
COLUMNS = ("eevee-rt", "eevee-rt-planar", "ours", "ours, screen alone", "ours, Cycles captures",
           "correct screen space", "perfect fallback", "correct reflections", "ours on Cycles' passes")
# The columns whose captures are costed: the captures' stages (and auto's choice), per frame render.
CAPTURE_STAGES = ("fallback_choice", "planar_capture", "cube_capture")
COSTED = ("ours", "ours, Cycles captures")


def measure(scene_name, frame_number, resolution, cache):
    """({column: FLIP on the reflective pixels}, {COSTED column: its captures' milliseconds as a
    multiple of the frame's render}) of one scene's FRAME_NUMBER-th frame."""
    path = resolve_scene(scene_name)
    scene = load_scene(path)
    frame = scene.frame_current + frame_number - 1
    reference = render_reference(scene, path, resolution, REFERENCE_SAMPLES, frame, cache)
    scene.frame_set(frame)
    images, costs = {}, {}
    with lamp_world_for_run():
        def render(method, engine="eevee", samples=EEVEE_SAMPLES, cost=None, **settings):
            request = RenderRequest(out_dir="", method=method, engine=engine, resolution=resolution, samples=samples,
                                    settings=replace(ChainSettings(), **settings))
            rendered, timer = render_frame(scene, request)
            if cost is not None:
                stages = timer.milliseconds
                costs[cost] = sum(stages.get(stage, 0.0) for stage in CAPTURE_STAGES) / stages["render"]
            return rendered
        images["eevee-rt"] = render("eevee-rt").final
        with TemporaryChanges() as changes:
            try:
                apply_baseline(scene, "planar", changes)
                images["eevee-rt-planar"] = render("eevee-rt").final
            except SSRError:
                pass  # no flat mesh to put EEVEE's plane probe on
        images["ours"] = render("ssr", cost="ours").final
        images["ours, Cycles captures"] = render("ssr", cost="ours, Cycles captures", capture_engine="cycles").final
        screen_alone = render("ssr", fallback="off")
        images["ours, screen alone"] = screen_alone.final
        with TemporaryChanges() as changes:
            changes.set(scene.cycles, "seed", CYCLES_SEED)
            on_cycles = render("ssr", "cycles", CYCLES_SAMPLES)
    images["ours on Cycles' passes"] = on_cycles.final
    eevee, cycles = screen_alone.passes, on_cycles.passes
    premultiplied, confidence = ideal_screen_space(scene, eevee)
    images["correct screen space"] = with_reflection(screen_alone, eevee.specular_color * premultiplied, confidence)
    cycles_reflection = cycles.specular_color * on_cycles.layers["Specular Indirect"]
    images["correct reflections"] = with_reflection(screen_alone, cycles_reflection,
                                                    np.ones(eevee.depth.shape, np.float32))
    missed = 1.0 - screen_alone.layers["SSR Confidence"][..., 0]
    images["perfect fallback"] = screen_alone.final[..., :3] + missed[..., None] * (
        cycles_reflection - eevee.specular_color * screen_alone.layers["Specular Indirect"])
    return {column: flip_error(reference.image, images[column][..., :3], reference.mask)
            for column in COLUMNS if column in images}, costs


def cost_table(costs):
    lines = ["| scene | " + " | ".join(f"{column}: captures" for column in COSTED) + " |",
             "|---" + "|---:" * len(COSTED) + "|"]
    for name, row in costs.items():
        lines.append(f"| {name} | " + " | ".join(f"{row[column]:.2f}x" for column in COSTED) + " |")
    return lines


def table(rows):
    lines = ["| scene | " + " | ".join(COLUMNS) + " |", "|---" + "|---:" * len(COLUMNS) + "|"]
    for name, scores in rows.items():
        baseline = scores["eevee-rt"]
        cells = ["-" if column not in scores else f"{scores[column]:.4f}"
                 + ("" if column == "eevee-rt" else f" ({scores[column] / baseline:.2f})") for column in COLUMNS]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    means = []
    for column in COLUMNS[1:]:
        ratios = [scores[column] / scores["eevee-rt"] for scores in rows.values() if column in scores]
        means.append(f"{np.exp(np.mean(np.log(ratios))):.2f}" if ratios else "-")
    lines.append("| geometric mean of the ratios | | " + " | ".join(means) + " |")
    return lines


def main(argv):
    parser = ArgumentParser(prog="python -m lab error-budget", description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(DEFAULT_SCENES))
    parser.add_argument("--frame", type=int, default=8, help="which frame of the scene's animation, from 1")
    parser.add_argument("--resolution", type=parse_resolution, default=(160, 90))
    parser.add_argument("--cache", default=DEFAULT_CACHE, help="folder of cached Cycles references (the bench's)")
    parser.add_argument("--page", help="rewrite the error-budget block of this markdown page")
    arguments = parser.parse_args(argv)
    require_page(arguments.page)
    measured = {name: measure(name, arguments.frame, arguments.resolution, arguments.cache) for name in arguments.scenes}
    rows = {name: scores for name, (scores, _) in measured.items()}
    width, height = arguments.resolution
    text = "\n".join([
        f"Latest run: `python -m lab error-budget --scenes {' '.join(arguments.scenes)} "
        f"--frame {arguments.frame} --resolution {width}x{height}"
        f"{' --page docs/measurements.md' if arguments.page else ''}`: FLIP on the reflective pixels of a still of "
        f"frame {arguments.frame} against the bench's Cycles reference ({REFERENCE_SAMPLES} samples); in brackets "
        f"as a multiple of EEVEE's ray tracing (the goal: at most {GOAL}). Ours on Cycles' passes: "
        f"{CYCLES_SAMPLES} samples.", "", *table(rows), "",
        "What the captures cost (auto's choice and the captures' renders, as a multiple of the frame's "
        "own render; 0: auto captured nothing):", "", *cost_table({name: cost for name, (_, cost) in measured.items()})])
    print(text)
    if arguments.page:
        rewrite_block(arguments.page, "error-budget", text, "Where the error comes from")
