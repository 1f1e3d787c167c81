"""What the fallback hierarchy's captures cost, drawn through a 3D View or rendered, and how close
a drawn capture is to a rendered one.

    python -m lab captures [--scenes NAME ...] [--resolutions WxH ...] [--page docs/measurements.md]

For each scene and resolution: the frame's own render (the second of two: the first compiles),
the same frame rendered with the guard band (level 1: wider by the default guard_band_size on
each side, a render of its own in place of the frame's), the planar capture and the depth cube
map rendered (scene_captures.render_*_capture, a fresh EEVEE instance each) and drawn through
the 3D View (GPUOffScreen.draw_view3d: the first draw, which compiles the viewport's shaders,
and the next after the camera moved). Drawn and rendered
planar captures are compared with a 64-sample render of the capture: the relative mean
absolute difference of their radiance, beside that of a render at the frame's samples (EEVEE's
own noise), and the frame's render right after a drawn capture: EEVEE's render and viewport
pipelines compile their shaders again for each other, which is why runs render their captures.
Also each capture rendered by Cycles (capture_engine=cycles), and the cube's six faces as one
multi-view render (six cameras, one view each) against six renders.
"""
import tempfile
import time

import bpy
import numpy as np
from mathutils import Matrix

from ssr_addon.blender.gpu_context import ensure_backend
from ssr_addon.blender.overrides import TemporaryChanges
from ssr_addon.blender.render_passes import render_passes
from ssr_addon.blender.render_setup import apply_render_setup, decide_render, rendered_view_layer
from ssr_addon.blender.scene_captures import (SceneCaptures, cube_centre, draw_cube_capture, draw_planar_capture,
                                              find_reflector, render_cube_capture, render_planar_capture)
from ssr_addon.blender.scene_io import camera_matrices, load_scene
from ssr_addon.blender.viewport_capture import headless_viewport
from ssr_addon.core.captures import cube_face_views
from ssr_addon.core.gpu_backend import describe_gpu
from ssr_addon.core.settings import ChainSettings
from .bench.scenes import resolve_scene, scene_label
from .docs import format_resolutions, require_page, rewrite_block, scenes_parser

# The room: every level has work there (a polished floor, walls and a glowing ceiling off screen).
SCENES = ("steel_room",)
# The two sizes: the bench's, and a user's preview render.
RESOLUTIONS = [(160, 90), (1280, 720)]
SAMPLES = 16
REFERENCE_SAMPLES = 64
CUBE_SIZE = 128
# The table's columns after the frame's render: measure()'s keys, and how the table names them.
HEADINGS = {"guard band render": "guard band render", "planar render": "planar render",
            "planar cycles": "planar Cycles", "planar draw first": "planar drawn, first",
            "planar draw": "planar drawn", "render after draw": "frame render after a draw",
            "cube render": "cube render", "cube cycles": "cube Cycles", "cube multi-view": "cube multi-view",
            "cube draw first": "cube drawn, first", "cube draw": "cube drawn"}


def _timed(make):
    started = time.perf_counter()
    result = make()
    return result, time.perf_counter() - started


def _relative(a, b):
    return float(np.abs(a[..., :3] - b[..., :3]).mean() / max(b[..., :3].mean(), 1e-6))


def render_cube_multiview(scene, side, changes):
    """The depth cube map's six faces as one multi-view render of six cameras (timing only: the
    add-on renders six)."""
    render = scene.render
    changes.set_all(render, resolution_x=side, resolution_y=side, use_multiview=True, views_format="MULTIVIEW")
    for view in render.views:
        changes.set(view, "use", False)
    base = bpy.data.objects.new("SSR Multi-View", bpy.data.cameras.new("SSR Multi-View"))
    made = [base]
    for index, view in enumerate(cube_face_views(cube_centre(scene))):
        data = bpy.data.cameras.new(f"SSR Multi-View_{index}")
        data.angle, data.sensor_fit = np.pi / 2, "HORIZONTAL"
        camera = bpy.data.objects.new(f"SSR Multi-View_{index}", data)
        camera.matrix_world = Matrix(np.linalg.inv(view).tolist())
        made.append(camera)
        added = render.views.new(f"face{index}")
        added.camera_suffix = f"_{index}"
        changes.on_restore(lambda added=added: render.views.remove(added))
    for camera in made:
        scene.collection.objects.link(camera)
        changes.on_restore(lambda camera=camera, data=camera.data: (bpy.data.objects.remove(camera),
                                                                    bpy.data.cameras.remove(data)))
    changes.set(scene, "camera", base)
    bpy.ops.render.render()


def measure(name, resolution):
    scene = load_scene(resolve_scene(name))
    ensure_backend()
    for _ in range(2):
        passes, render_s = _timed(lambda: render_passes(scene, decide_render(scene, samples=SAMPLES,
                                                                             resolution=resolution)))
    guard_band = decide_render(scene, samples=SAMPLES, resolution=resolution,
                               guard_band=ChainSettings().guard_band_size)
    found = find_reflector(scene, passes, 1.0)
    found = found[:2] if found is not None else None
    row = {"scene": scene_label(resolve_scene(name)), "resolution": "{}x{}".format(*resolution), "render": render_s,
           "guard band render": _timed(lambda: render_passes(scene, guard_band))[1]}
    view_layer = rendered_view_layer(scene)

    def rendered(kind, samples, capture_engine="eevee"):
        setup = decide_render(scene, samples=samples, resolution=resolution, capture_engine=capture_engine)
        with tempfile.TemporaryDirectory() as folder, TemporaryChanges() as changes:
            apply_render_setup(setup, scene, view_layer, changes)
            SceneCaptures.use_capture_engine(scene, setup, changes)
            if kind == "planar":
                return render_planar_capture(scene, resolution, *found, folder, changes)
            return render_cube_capture(scene, CUBE_SIZE, folder, changes)

    def drawn(kind, viewport):
        setup = decide_render(scene, samples=SAMPLES, resolution=resolution)
        with TemporaryChanges() as changes:
            apply_render_setup(setup, scene, view_layer, changes)
            if kind == "planar":
                return draw_planar_capture(scene, view_layer, viewport, camera_matrices(scene, *resolution), resolution,
                                           SAMPLES, *found, changes)
            return draw_cube_capture(scene, view_layer, viewport, CUBE_SIZE, SAMPLES)

    viewport = headless_viewport()
    held = TemporaryChanges()
    viewport.hold_for_captures(held)
    try:
        for kind in ("planar", "cube"):
            if kind == "planar" and found is None:
                continue
            row[f"{kind} render"] = _timed(lambda: rendered(kind, SAMPLES))[1]
            row[f"{kind} cycles"] = _timed(lambda: rendered(kind, SAMPLES, "cycles"))[1]
            if kind == "cube":
                with TemporaryChanges() as changes:
                    apply_render_setup(decide_render(scene, samples=SAMPLES, resolution=resolution), scene,
                                       view_layer, changes)
                    row["cube multi-view"] = _timed(lambda: render_cube_multiview(scene, CUBE_SIZE, changes))[1]
            first, row[f"{kind} draw first"] = _timed(lambda: drawn(kind, viewport))
            camera = scene.camera
            camera.location.x += 0.01  # a moved view: the viewport must draw afresh
            warm, row[f"{kind} draw"] = _timed(lambda: drawn(kind, viewport))
            camera.location.x -= 0.01
            if kind == "planar":
                # What a run would pay: the frame's render after a drawn capture, the pipelines
                # taking turns.
                _, after = _timed(lambda: render_passes(scene, decide_render(scene, samples=SAMPLES,
                                                                             resolution=resolution)))
                row["render after draw"] = after
            if kind == "planar":
                reference = rendered(kind, REFERENCE_SAMPLES).radiance
                row["planar error"] = (_relative(drawn(kind, viewport).radiance, reference),
                                       _relative(rendered(kind, SAMPLES).radiance, reference))
    finally:
        held.restore()
        viewport.release()
    return row


def main(argv):
    arguments = scenes_parser("captures", __doc__, SCENES, RESOLUTIONS, "capture-cost").parse_args(argv)
    require_page(arguments.page)
    rows = [measure(name, resolution) for name in arguments.scenes for resolution in arguments.resolutions]
    lines = [f"Latest run: `python -m lab captures --scenes {' '.join(arguments.scenes)} "
             f"--resolutions {format_resolutions(arguments.resolutions)}"
             f"{' --page docs/measurements.md' if arguments.page else ''}` on {describe_gpu()['renderer']}; "
             f"EEVEE at {SAMPLES} samples, cube faces {CUBE_SIZE}x{CUBE_SIZE}. Seconds, and in brackets as a "
             f"multiple of the frame's own render. Drawn: through the 3D View, first (compiling) and after "
             f"the camera moved. Planar error: relative mean absolute difference from a {REFERENCE_SAMPLES}-sample "
             f"render of the capture, drawn / rendered at {SAMPLES} samples (EEVEE's own noise).", "",
             "| " + " | ".join(("scene", "resolution", "frame render s") + tuple(HEADINGS.values())
                             + ("planar error drawn / rendered",)) + " |",
             "|---" * (len(HEADINGS) + 4) + "|"]
    for row in rows:
        def cell(key):
            return f"{row[key]:.2f} ({row[key] / row['render']:.2f}x)" if key in row else "-"
        error = row.get("planar error")
        lines.append(f"| {row['scene']} | {row['resolution']} | {row['render']:.2f} | "
                     + " | ".join(cell(key) for key in HEADINGS)
                     + f" | {f'{error[0]:.2%} / {error[1]:.2%}' if error else '-'} |")
    text = "\n".join(lines)
    print(text)
    if arguments.page:
        rewrite_block(arguments.page, "capture-cost", text, "What the captures cost")
