"""The deck's opening slides: SSR on and off, the cubemap and planar baselines (rows of
_MODE_SLIDES), the planar probe's cost as the scene grows, and the basic algorithm's inputs."""
import os

import bmesh
import bpy
import numpy as np

from ..bench.charts import chart_cost_by_count
from ssr_addon.blender.overrides import TemporaryChanges
from .section import section

MIRROR = "mirror_floor"  # a sphere and boxes over a mirror floor: the deck's opening example


def _modes_side_by_side(key, title, scene, tiles, caption, more=None):
    """The builder of a section of SCENE rendered in each comparison mode of TILES ((mode, label,
    name) each), with each one's error against Cycles and milliseconds as NAME_flip,
    NAME_rel_mae and NAME_ms; MORE(context, key, scene), when given, adds (images, numbers)."""
    def build(context):
        images, numbers = [], {}
        for mode, label, name in tiles:
            render = context.render(scene, mode)
            numbers.update({f"{name}_{metric}": value for metric, value in context.error(scene, render).items()})
            numbers[f"{name}_ms"] = round(render.wall_ms)
            images.append((label, context.save(f"{key}_{name}.png", render.final)))
        if more:
            more_images, more_numbers = more(context, key, scene)
            images += more_images
            numbers.update(more_numbers)
        return section(title, images, numbers, caption)
    build.__name__ = key  # the section's id
    return build


def _planar_cost(context, key, name):
    """A chart of scene NAME's frame time with no reflection and with the planar probe as the
    scene gains objects, and the probe's added milliseconds with none and with the most added."""
    counts = (0, 16, 64) if context.quick else (0, 50, 200, 800)
    curves = {"no reflection": [], "planar probe": []}
    for count in counts:
        with TemporaryChanges() as changes:
            _scatter_spheres(context.scene(name), changes, count)
            for curve, mode in (("no reflection", "NONE"), ("planar probe", "PLANAR")):
                curves[curve].append(round(context.render_afresh(name, mode).wall_ms))
    file_name = f"{key}_cost.png"
    chart_cost_by_count(counts, curves, os.path.join(context.out_dir, file_name), "objects added to the scene",
                        "milliseconds a frame", f"Frame time as the scene grows, "
                        f"{context.resolution[0]}x{context.resolution[1]}, {context.samples} samples")
    added = [planar - none for planar, none in zip(curves["planar probe"], curves["no reflection"])]
    return ([("Frame time against object count", file_name, "chart")],
            {"planar_added_ms": added[0], "planar_added_ms_grown": added[-1], "objects_added": counts[-1]})


def _scatter_spheres(scene, changes, count, columns=8, rows=10):
    """COUNT small spheres, each its own mesh and object, on a grid of COLUMNS x ROWS behind the
    scene's objects (where the mirror shows them), layer above layer; CHANGES removes them."""
    template = bpy.data.meshes.new("SlideSphere")
    sphere = bmesh.new()
    bmesh.ops.create_uvsphere(sphere, u_segments=16, v_segments=8, radius=0.12)
    sphere.to_mesh(template)
    sphere.free()
    added = []
    for index in range(count):
        column, row, layer = index % columns, index // columns % rows, index // (columns * rows)
        obj = bpy.data.objects.new(f"SlideSphere{index}", template.copy())
        obj.location = (-4.0 + 8.0 * column / (columns - 1), 6.5 + 0.4 * row, 0.12 + 0.3 * layer)
        scene.collection.objects.link(obj)
        added.append(obj)

    def remove():
        for obj in added:
            mesh = obj.data
            bpy.data.objects.remove(obj)
            bpy.data.meshes.remove(mesh)
        bpy.data.meshes.remove(template)
    changes.on_restore(remove)


# The slides that set one comparison mode beside another on the mirror floor: (key, the deck's
# title, tiles (mode, label, name), more (see _modes_side_by_side) or None, caption).
_MODE_SLIDES = (
    ("ssr_on_off", "SSR: ON / SSR: OFF",
     (("NONE", "SSR off (world and probes only)", "off"), ("SSR", "SSR on (balanced)", "on")), None,
     "Look at the floor: without SSR it reflects only the world, so the sphere and the boxes have no "
     "reflection. Error against Cycles on the reflective pixels: FLIP {off_flip} off, {on_flip} on "
     "(relative MAE {off_rel_mae} and {on_rel_mae}); a frame took {off_ms} ms off and {on_ms} ms on."),
    ("cubemaps", "What about cubemaps?",
     (("CUBEMAP", "One cubemap, captured over the scene's middle at eye height", "cubemap"),
      ("SSR", "SSR", "ssr")), None,
     "A cubemap sees the scene from one point: reflections of nearby objects land in the wrong place "
     "and stretch, and nothing reflects itself. A game captures it ahead of time, so moving objects are not "
     "in it (this one is captured again for every frame, so it holds them). "
     "FLIP against Cycles: cubemap {cubemap_flip}, SSR {ssr_flip} (relative MAE {cubemap_rel_mae} and "
     "{ssr_rel_mae}); {cubemap_ms} ms and {ssr_ms} ms a frame."),
    ("planar", "Planar Reflections",
     (("PLANAR", "Planar probe on the floor", "planar"), ("CUBEMAP", "Cubemap", "cubemap")), _planar_cost,
     "Rendering the scene again from the mirrored viewpoint is exact for the one plane, and only for it; "
     "its cost grows with the scene: the probe re-renders every object, {planar_added_ms} ms more a frame "
     "than no reflection here and {planar_added_ms_grown} ms more with {objects_added} small objects added. "
     "FLIP against Cycles: planar {planar_flip}, cubemap {cubemap_flip} "
     "(relative MAE {planar_rel_mae} and {cubemap_rel_mae}); {planar_ms} ms and {cubemap_ms} ms a frame."),
)


def basic_algorithm(context):
    ssr = context.render(MIRROR, "SSR")
    passes = ssr.images.passes
    depth = np.where(passes.depth < 1e9, passes.depth, np.nan)
    near, far = np.nanmin(depth), np.nanmax(depth)
    depth_shown = np.nan_to_num(1.0 - (depth - near) / max(far - near, 1e-6), nan=0.0)
    reflection = ssr.images.layers["SSR Reflection"]
    numbers = {"traced_fraction": round(float((ssr.images.layers["SSR Ray Class"][..., 0] > 0).mean()), 3),
               "iterations": ssr.images.stats["iterations"]}
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


INTRO_SECTIONS = (*(_modes_side_by_side(key, title, MIRROR, tiles, caption, more)
                    for key, title, tiles, more, caption in _MODE_SLIDES), basic_algorithm)
