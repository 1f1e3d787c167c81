"""The deck's comparisons, one builder per slide (a function, or a row of _MODE_SLIDES). Each
returns a section: the deck's title, the images side by side ({label, file}), the numbers
measured and a caption whose {fields} are those numbers (page.py fills them in, so the page
shows exactly what slides.json holds)."""
import numpy as np

from ..bench.images import display
from ..params import ChainSettings

MIRROR = "mirror_floor"  # a sphere and boxes over a mirror floor: the deck's opening example
THIN = "stability_thin"  # thin poles and a crossbar over a glossy floor: fine detail for the stride


def _section(key, title, images, numbers, caption):
    return {"id": key, "title": title, "images": [{"label": label, "file": file} for label, file in images],
            "numbers": numbers, "caption": caption}


def _modes_side_by_side(key, title, scene, tiles, caption):
    """The builder of a section of SCENE rendered in each comparison mode of TILES ((mode, label,
    name) each), with each one's error against Cycles and milliseconds as NAME_flip,
    NAME_rel_mae and NAME_ms."""
    def build(context):
        images, numbers = [], {}
        for mode, label, name in tiles:
            render = context.render(scene, mode)
            numbers.update({f"{name}_{metric}": value for metric, value in context.error(scene, render).items()})
            numbers[f"{name}_ms"] = round(render.wall_ms)
            images.append((label, context.save(f"{key}_{name}.png", render.final)))
        return _section(key, title, images, numbers, caption)
    return build


# The slides that set one comparison mode beside another on the mirror floor: (key, the deck's
# title, tiles (mode, label, name), caption).
_MODE_SLIDES = (
    ("ssr_on_off", "SSR: ON / SSR: OFF",
     (("NONE", "SSR off (world and probes only)", "off"), ("SSR", "SSR on (balanced)", "on")),
     "Look at the floor: without SSR it reflects only the world, so the sphere and the boxes have no "
     "reflection. Error against Cycles on the reflective pixels: FLIP {off_flip} off, {on_flip} on "
     "(relative MAE {off_rel_mae} and {on_rel_mae}); a frame took {off_ms} ms off and {on_ms} ms on."),
    ("cubemaps", "What about cubemaps?",
     (("CUBEMAP", "One cubemap, captured at the scene's centre", "cubemap"), ("SSR", "SSR", "ssr")),
     "A cubemap sees the scene from one point: reflections of nearby objects land in the wrong place "
     "and stretch, and nothing reflects itself. It is captured once, so moving objects are not in it. "
     "FLIP against Cycles: cubemap {cubemap_flip}, SSR {ssr_flip} (relative MAE {cubemap_rel_mae} and "
     "{ssr_rel_mae}); {cubemap_ms} ms and {ssr_ms} ms a frame."),
    ("planar", "Planar Reflections",
     (("PLANAR", "Planar probe on the floor", "planar"), ("CUBEMAP", "Cubemap", "cubemap")),
     "Rendering the scene again from the mirrored viewpoint is exact for the one plane, and only for it; "
     "its cost grows with the scene. FLIP against Cycles: planar {planar_flip}, cubemap {cubemap_flip} "
     "(relative MAE {planar_rel_mae} and {cubemap_rel_mae}); {planar_ms} ms and {cubemap_ms} ms a frame."),
)


def basic_algorithm(context):
    ssr = context.render(MIRROR, "SSR")
    passes = ssr.images["passes"]
    depth = np.where(passes.depth < 1e9, passes.depth, np.nan)
    near, far = np.nanmin(depth), np.nanmax(depth)
    depth_shown = np.nan_to_num(1.0 - (depth - near) / max(far - near, 1e-6), nan=0.0)
    reflection = ssr.images["reflection"][..., :3]
    numbers = {"traced_fraction": round(float((ssr.images["ray_stats"][..., 0] > 0).mean()), 3),
               "iterations": ssr.images["stats"]["iterations"]}
    return _section("basic_algorithm", "Basic SSR Algorithm - Mirror Reflection", [
        ("Shaded scene", context.save("inputs_shaded.png", passes.combined[..., :3])),
        ("Normals (world space)", context.save("inputs_normals.png", passes.normal * 0.5 + 0.5, data=True)),
        ("Depth (near is bright)", context.save("inputs_depth.png", np.repeat(depth_shown[..., None], 3, -1),
                                               data=True)),
        ("SSR (reflected light, premultiplied)", context.save("inputs_ssr.png", reflection)),
        ("Shaded scene with SSR", context.save("inputs_final.png", ssr.final))], numbers,
        "Each pixel's reflection ray is marched through the depth buffer and reads the shaded scene where "
        "it hits. {traced_fraction} of the pixels here traced a ray; the still accumulated {iterations} "
        "iterations.")


def linear_raymarch(context):
    images, numbers = [], {}
    for stride, refine in ((1, 6), (16, 6), (16, 0)):
        render = context.render(THIN, "SSR", use_hiz=False, trace_stride=float(stride), refine_steps=refine,
                                trace_steps=256 // stride)
        key = f"stride{stride}" + ("" if refine else "_unrefined")
        numbers[f"{key}_flip"] = context.error(THIN, render)["flip"]
        numbers[f"{key}_trace_ms"] = round(render.stages_ms.get("trace", 0.0), 1)
        label = f"stride {stride} px, " + (f"{refine} refinement steps" if refine else "no refinement")
        images.append((label, context.save(f"linear_{key}.png", render.final)))
    return _section("linear_raymarch", "Linear Raymarch", images, numbers,
                    "Quality depends on the step size, and the march can be refined. Over the same reach "
                    "a 16-pixel stride takes a sixteenth of the steps; its refinement steps bisect back to "
                    "the surface, and without them the reflection of the crossbar breaks into bands of the "
                    "stride. FLIP against Cycles: stride 1 {stride1_flip}, stride 16 {stride16_flip}, "
                    "unrefined {stride16_unrefined_flip}; the trace took {stride1_trace_ms}, "
                    "{stride16_trace_ms} and {stride16_unrefined_trace_ms} ms.")


def cheap_and_expensive_rays(context):
    render = context.render("rough_spheres", "SSR")
    ray_class = render.images["ray_stats"][..., 0]
    colours = np.zeros(ray_class.shape + (3,))
    colours[ray_class == 1] = (0.2, 0.5, 1.0)  # cheap: linear march
    colours[ray_class == 2] = (1.0, 0.5, 0.1)  # expensive: Hi-Z
    traced = np.count_nonzero(ray_class > 0)
    settings = ChainSettings()
    numbers = {"expensive_share": round(np.count_nonzero(ray_class == 2) / max(traced, 1), 3),
               "budget": settings.expensive_ray_budget, "sharp_roughness": settings.sharp_roughness,
               "trace_ms": round(render.stages_ms.get("trace", 0.0), 1)}
    return _section("cheap_expensive_rays", "Use cheap rays / Use expensive rays", [
        ("Image", context.save("rays_image.png", render.final)),
        ("Ray class: blue cheap (linear), orange expensive (Hi-Z)",
         context.save("rays_class.png", 0.3 * display(render.final) + 0.7 * colours, data=True))], numbers,
        "Smooth surfaces get the expensive Hi-Z rays, rough ones cheap linear rays. The deck keeps Hi-Z "
        "rays under 20 %; the balanced preset gives them to the smoothest {budget} of the reflecting pixels "
        "and to every surface smoother than {sharp_roughness}, which on these polished spheres is most: "
        "{expensive_share} of the traced rays were expensive, and tracing took {trace_ms} ms.")


SECTIONS = (*(_modes_side_by_side(key, title, MIRROR, tiles, caption) for key, title, tiles, caption in _MODE_SLIDES),
            basic_algorithm, linear_raymarch, cheap_and_expensive_rays)
