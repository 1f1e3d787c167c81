"""The deck's tracing slides: the linear raymarch, cheap against expensive rays and one ray's
hierarchical (Hi-Z) walk."""
import os

import numpy as np

from ..bench.images import display
from ssr_addon.core.inputs import ChainInputs
from ..hiz_walk import most_instructive_walk
from ssr_addon.core.settings import ChainSettings
from .hiz_diagram import draw_hiz_walk
from .intro import MIRROR
from .section import section

THIN = "stability_thin"  # thin poles and a crossbar over a glossy floor: fine detail for the stride


def linear_raymarch(context):
    images, numbers = [], {}
    for stride, refine in ((1, 6), (4, 6), (16, 6), (16, 0)):
        render, = context.chain(THIN, use_hiz=False, trace_stride=float(stride), refine_steps=refine,
                                trace_steps=256 // stride)
        key = f"stride{stride}" + ("" if refine else "_unrefined")
        numbers[f"{key}_flip"] = context.error(THIN, render)["flip"]
        numbers[f"{key}_trace_ms"] = render.iteration_ms("trace")
        label = f"stride {stride} px, " + (f"{refine} refinement steps" if refine else "no refinement")
        images.append((label, context.save(f"linear_{key}.png", render.final)))
    return section("Linear Raymarch", images, numbers,
                    "Quality depends on the step size, and the march can be refined. Over the same reach "
                    "a 4-pixel stride takes a quarter of the steps and a 16-pixel one a sixteenth; refinement "
                    "steps bisect back to the surface, and without them the reflection of the crossbar "
                    "breaks into bands of the stride. A step hits when the ray's depth over it overlaps the "
                    "surface's, so a long step also counts rays that pass just behind a pole: thin things "
                    "reflect thicker. FLIP against Cycles: stride 1 {stride1_flip}, stride 4 {stride4_flip}, "
                    "stride 16 {stride16_flip}, unrefined {stride16_unrefined_flip}; an iteration's trace took "
                    "{stride1_trace_ms}, {stride4_trace_ms}, {stride16_trace_ms} and "
                    "{stride16_unrefined_trace_ms} ms.")


ROUGH = "rough_spheres"  # spheres of rising roughness over a polished floor: every ray class
# The ray budgets compared: (name, chain settings, label). The deck's keeps Hi-Z rays under 20 %.
_RAY_BUDGETS = (
    ("balanced", {}, "balanced"),
    ("deck", dict(expensive_ray_budget=0.2, sharp_roughness=0.0), "the deck's: 20 %, smoothest first"),
    ("cheap", dict(use_hiz=False), "no expensive rays"))


def _ray_class_colours(render):
    """RENDER's image dimmed under its ray classes: blue cheap (linear), orange expensive (Hi-Z)."""
    ray_class = render.images.layers["SSR Ray Class"][..., 0]
    colours = np.zeros(ray_class.shape + (3,))
    colours[ray_class == 1] = (0.2, 0.5, 1.0)
    colours[ray_class == 2] = (1.0, 0.5, 0.1)
    return 0.3 * display(render.final) + 0.7 * colours


def cheap_and_expensive_rays(context):
    images, numbers = [], {}
    for name, settings, label in _RAY_BUDGETS:
        render, = context.chain(ROUGH, **settings)
        ray_class = render.images.layers["SSR Ray Class"][..., 0]
        if settings.get("use_hiz", True):
            numbers[f"{name}_expensive_share"] = round(np.count_nonzero(ray_class == 2)
                                                       / max(np.count_nonzero(ray_class > 0), 1), 3)
        numbers[f"{name}_trace_ms"] = render.iteration_ms("trace")
        numbers[f"{name}_flip"] = context.error(ROUGH, render)["flip"]
        if name == "balanced":
            images.append(("Image", context.save("rays_image.png", render.final)))
        images.append((f"Ray classes, {label}: blue cheap (linear), orange expensive (Hi-Z)",
                       context.save(f"rays_class_{name}.png", _ray_class_colours(render), data=True)))
    settings = ChainSettings()
    numbers.update(budget=settings.expensive_ray_budget, sharp_roughness=settings.sharp_roughness)
    return section(
        "Use cheap rays / Use expensive rays", images, numbers,
        "Smooth surfaces get the expensive Hi-Z rays, rough ones cheap linear rays. The balanced preset "
        "gives them to the smoothest {budget} of the reflecting pixels and to every surface smoother than "
        "{sharp_roughness}, which on these polished spheres and floor is most: {balanced_expensive_share} "
        "of the traced rays. The deck keeps them under 20 %: with a 20 % budget, {deck_expensive_share} of "
        "the rays here. An iteration's trace took {balanced_trace_ms} ms, {deck_trace_ms} ms with the deck's "
        "budget and {cheap_trace_ms} ms with cheap rays only; FLIP against Cycles {balanced_flip}, {deck_flip} and "
        "{cheap_flip}.")


def hierarchical_ray_trace(context):
    passes = context.render(MIRROR).images.passes
    settings = ChainSettings()
    height, width = passes.depth.shape
    # Candidates: the mirror floor below the marker, down the middle of the frame.
    candidates = [(width // 2 + offset, row) for row in range(height // 2, height, max(height // 24, 1))
                  for offset in (-width // 16, 0, width // 16)]
    walk = most_instructive_walk(ChainInputs.from_passes(passes, settings), settings, candidates)
    draw_hiz_walk(walk, passes.depth, os.path.join(context.out_dir, "hiz_walk.png"))
    linear, = context.chain(THIN, use_hiz=False, trace_stride=16.0, trace_steps=16, refine_steps=0)
    hierarchical, = context.chain(THIN, expensive_ray_budget=1.0)
    numbers = {"visits": walk.iterations, "pixel_tests": walk.pixel_tests, "highest_level": walk.highest_level,
               "linear_flip": context.error(THIN, linear)["flip"],
               "hiz_flip": context.error(THIN, hierarchical)["flip"],
               "linear_trace_ms": linear.iteration_ms("trace"), "hiz_trace_ms": hierarchical.iteration_ms("trace"),
               "pyramid_ms": round(hierarchical.stages_ms.get("hiz", 0.0), 1)}
    return section("Hierarchical ray trace (Expensive)", [
        ("One mirror ray of the floor, walked through the min-depth pyramid", "hiz_walk.png", "chart"),
        ("Linear march, 16-pixel steps, unrefined", context.save("hiz_linear.png", linear.final)),
        ("Every ray hierarchical (Hi-Z)", context.save("hiz_every_ray.png", hierarchical.final))], numbers,
        "The depth pyramid keeps each cell's nearest depth, so a ray that passes in front of a whole cell "
        "cannot hit anything in it: it skips the cell and climbs a level; where it may hit, it descends. "
        "This ray reached level {highest_level} and found its hit in {visits} cell visits, where a "
        "pixel-by-pixel walk tests {pixel_tests} pixels. It cannot miss tiny geometry: a long linear "
        "step can jump a thin pole, while the walk only skips cells whose nearest depth lies behind the "
        "ray. FLIP against Cycles on the thin poles: {linear_flip} for 16-pixel linear steps, {hiz_flip} "
        "with every ray hierarchical; an iteration's trace took {linear_trace_ms} ms and {hiz_trace_ms} ms, "
        "and building the pyramid, once a frame, {pyramid_ms} ms.")
