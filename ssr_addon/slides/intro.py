"""The deck's opening slides: SSR on and off, the cubemap and planar baselines (rows of
_MODE_SLIDES) and the basic algorithm's inputs."""
import numpy as np

from .section import section

MIRROR = "mirror_floor"  # a sphere and boxes over a mirror floor: the deck's opening example


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
        return section(title, images, numbers, caption)
    build.__name__ = key  # the section's id
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
     (("CUBEMAP", "One cubemap, captured over the scene's middle at eye height", "cubemap"),
      ("SSR", "SSR", "ssr")),
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
    return section("Basic SSR Algorithm - Mirror Reflection", [
        ("Shaded scene", context.save("inputs_shaded.png", passes.combined[..., :3])),
        ("Normals (world space)", context.save("inputs_normals.png", passes.normal * 0.5 + 0.5, data=True)),
        ("Depth (near is bright)", context.save("inputs_depth.png", np.repeat(depth_shown[..., None], 3, -1),
                                               data=True)),
        ("SSR (reflected light, premultiplied)", context.save("inputs_ssr.png", reflection)),
        ("Shaded scene with SSR", context.save("inputs_final.png", ssr.final))], numbers,
        "Each pixel's reflection ray is marched through the depth buffer and reads the shaded scene where "
        "it hits. {traced_fraction} of the pixels here traced a ray; the still accumulated {iterations} "
        "iterations.")


INTRO_SECTIONS = (*(_modes_side_by_side(key, title, MIRROR, tiles, caption)
                    for key, title, tiles, caption in _MODE_SLIDES), basic_algorithm)
