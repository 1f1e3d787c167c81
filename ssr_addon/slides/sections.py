"""The deck's comparisons, one function per slide. Each returns a section: the deck's title, the
images side by side ({label, file}), the numbers measured and a caption whose {fields} are
those numbers (page.py fills them in, so the page shows exactly what slides.json holds)."""
import numpy as np

from ..bench.images import display
from ..params import ChainSettings

MIRROR = "mirror_floor"  # a sphere and boxes over a mirror floor: the deck's opening example
THIN = "stability_thin"  # a thin pole over a glossy floor: what a long stride steps over


def _section(key, title, images, numbers, caption):
    return {"id": key, "title": title, "images": [{"label": label, "file": file} for label, file in images],
            "numbers": numbers, "caption": caption}


def ssr_on_off(context):
    off, on = context.render(MIRROR, "NONE"), context.render(MIRROR, "SSR")
    numbers = {"off_ms": round(off.wall_ms), "on_ms": round(on.wall_ms),
               **{f"off_{k}": v for k, v in context.error(MIRROR, off).items()},
               **{f"on_{k}": v for k, v in context.error(MIRROR, on).items()}}
    return _section("ssr_on_off", "SSR: ON / SSR: OFF", [
        ("SSR off (world and probes only)", context.save("ssr_off.png", off.final)),
        ("SSR on (balanced)", context.save("ssr_on.png", on.final))], numbers,
        "Look at the floor: without SSR it reflects only the world, so the sphere and the boxes have no "
        "reflection. Error against Cycles on the reflective pixels: FLIP {off_flip} off, {on_flip} on "
        "(relative MAE {off_rel_mae} and {on_rel_mae}); a frame took {off_ms} ms off and {on_ms} ms on.")


def cubemaps(context):
    cubemap, ssr = context.render(MIRROR, "CUBEMAP"), context.render(MIRROR, "SSR")
    numbers = {"cubemap_flip": context.error(MIRROR, cubemap)["flip"], "ssr_flip": context.error(MIRROR, ssr)["flip"],
               "cubemap_ms": round(cubemap.wall_ms), "ssr_ms": round(ssr.wall_ms)}
    return _section("cubemaps", "What about cubemaps?", [
        ("One cubemap, captured at the scene's centre", context.save("cubemap.png", cubemap.final)),
        ("SSR", context.save("cubemap_ssr.png", ssr.final))], numbers,
        "A cubemap sees the scene from one point: reflections of nearby objects land in the wrong place "
        "and stretch, and nothing reflects itself. It is captured once, so moving objects are not in it. "
        "FLIP against Cycles: cubemap {cubemap_flip}, SSR {ssr_flip}; {cubemap_ms} ms and {ssr_ms} ms a frame.")


def planar(context):
    plane, cubemap = context.render(MIRROR, "PLANAR"), context.render(MIRROR, "CUBEMAP")
    numbers = {"planar_flip": context.error(MIRROR, plane)["flip"],
               "cubemap_flip": context.error(MIRROR, cubemap)["flip"],
               "planar_ms": round(plane.wall_ms), "cubemap_ms": round(cubemap.wall_ms)}
    return _section("planar", "Planar Reflections", [
        ("Planar probe on the floor", context.save("planar.png", plane.final)),
        ("Cubemap", context.save("planar_cubemap.png", cubemap.final))], numbers,
        "Rendering the scene again from the mirrored viewpoint is exact for the one plane, and only for it; "
        "its cost grows with the scene. FLIP against Cycles: planar {planar_flip}, cubemap {cubemap_flip}; "
        "{planar_ms} ms and {cubemap_ms} ms a frame.")


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
                    "Quality depends on the step size: a long stride steps over the thin pole's reflection "
                    "and, unrefined, lands in stair-steps. FLIP against Cycles: stride 1 {stride1_flip}, "
                    "stride 16 {stride16_flip}, unrefined {stride16_unrefined_flip}; the trace took "
                    "{stride1_trace_ms}, {stride16_trace_ms} and {stride16_unrefined_trace_ms} ms.")


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


SECTIONS = (ssr_on_off, cubemaps, planar, basic_algorithm, linear_raymarch, cheap_and_expensive_rays)
