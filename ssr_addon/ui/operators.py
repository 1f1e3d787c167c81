"""Operators: render the current frame, the animation or a comparison sheet, and
wire the result into the compositor.

Each renders through the batch layer's frame loop, with the comparison mode's baseline
applied for the duration of the render (batch.compare). Errors the user can fix
(SSRError) become one line in the status bar, never a traceback.
"""
import os
import time
from dataclasses import replace

import bpy

from ..batch.compare import MODE_METHODS, compare_modes, render_mode
from ..batch.request import RenderRequest
from ..batch.run import RenderRun
from ..blender.comparison_sheet import SHEET_IMAGE
from ..blender.compositor import setup_compositor
from ..blender.result_image import RESULT_IMAGE, forget_last_result, publish_image, publish_result
from ..core.errors import SSRError
from ..core.gpu_passes import release_passes
from ..core.settings import PRESETS, SETTINGS_SCHEMA, preset
from .properties import chain_settings


def output_folder(scene):
    """The folder of the scene's output path (Output properties; its last part is a file prefix)."""
    folder = os.path.dirname(bpy.path.abspath(scene.render.filepath))
    if not folder:
        raise SSRError(f"scene '{scene.name}' has no output path: set one in the Output properties")
    return folder


def output_prefix(scene):
    """The file prefix of the scene's output path ("//shots/take_" -> "take_"), as F12 renders name frames."""
    return os.path.basename(bpy.path.abspath(scene.render.filepath))


def render_request(scene, out_dir=""):
    """The RenderRequest of the scene's SSR settings; OUT_DIR only matters to frames that are written."""
    return RenderRequest(out_dir=out_dir, settings=chain_settings(scene.ssr))


def _baseline_choices(scene):
    return {"probe_object": scene.ssr.probe_object, "mirror_object": scene.ssr.planar_object}


def _show_in_image_editors(context, image):
    for area in context.screen.areas if context.screen else ():
        if area.type == "IMAGE_EDITOR":
            area.spaces.active.image = image


class _ReportsErrors:
    """execute() runs self.run(context); an SSRError becomes an error report and CANCELLED."""

    def execute(self, context):
        try:
            return self.run(context)
        except SSRError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}


class RENDER_OT_ssr_render_frame(_ReportsErrors, bpy.types.Operator):
    """Render the current frame in the chosen comparison mode into the "SSR Result" image"""
    bl_idname = "render.ssr_render_frame"
    bl_label = "Render SSR Frame"

    def run(self, context):
        scene = context.scene
        started = time.perf_counter()
        images, _ = render_mode(scene, scene.ssr.comparison_mode, render_request(scene), **_baseline_choices(scene))
        image = publish_result(images, scene.ssr.debug_view)
        _show_in_image_editors(context, image)
        self.report({"INFO"}, f"{RESULT_IMAGE}: frame {scene.frame_current} in {time.perf_counter() - started:.1f} s")
        return {"FINISHED"}


class RENDER_OT_ssr_render_animation(_ReportsErrors, bpy.types.Operator):
    """Render the scene's frame range in the chosen comparison mode into the output folder (Esc cancels)"""
    bl_idname = "render.ssr_render_animation"
    bl_label = "Render SSR Animation"

    def _frames(self, scene):
        """Render and write one frame per step through the command line's frame loop (RenderRun:
        resume, warm-up, camera cuts, report.json), so a modal operator can step it between events."""
        mode = scene.ssr.comparison_mode
        request = replace(render_request(scene, output_folder(scene)), frames=(scene.frame_start, scene.frame_end),
                          method=MODE_METHODS[mode], mode=mode, file_prefix=output_prefix(scene),
                          overwrite=scene.render.use_overwrite)
        choices = _baseline_choices(scene)

        def render_in_mode(scene, request, state, fallbacks):
            return render_mode(scene, mode, request, state, fallbacks, **choices)
        run = RenderRun(scene, bpy.data.filepath, request, render=render_in_mode, unsaved_changes=bpy.data.is_dirty)
        for frame, images in run.frames():
            publish_result(images, scene.ssr.debug_view)
            yield frame

    def _start(self, context):
        self._scene = context.scene
        self._initial_frame = self._scene.frame_current
        self._steps = self._frames(self._scene)
        self._done = 0

    def _finish(self, context):
        self._steps.close()
        self._scene.frame_set(self._initial_frame)

    def run(self, context):
        """Synchronous: background mode and scripts."""
        self._start(context)
        try:
            for _ in self._steps:
                self._done += 1
        finally:
            self._finish(context)
        self._report_written()
        return {"FINISHED"}

    def _report_written(self):
        self.report({"INFO"}, f"{self._done} frames written to {output_folder(self._scene)}")

    def invoke(self, context, event):
        if bpy.app.background:
            return self.execute(context)
        self._start(context)
        wm = context.window_manager
        wm.progress_begin(0, self._scene.frame_end - self._scene.frame_start + 1)
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _end_modal(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        self._finish(context)

    def modal(self, context, event):
        if event.type == "ESC":
            self._end_modal(context)
            self.report({"WARNING"}, f"SSR animation cancelled after {self._done} frames")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}
        try:
            next(self._steps)
        except StopIteration:
            self._end_modal(context)
            self._report_written()
            return {"FINISHED"}
        except SSRError as error:
            self._end_modal(context)
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self._done += 1
        context.window_manager.progress_update(self._done)
        return {"RUNNING_MODAL"}


class RENDER_OT_ssr_compare(_ReportsErrors, bpy.types.Operator):
    """Render the current frame in every comparison mode, side by side and labelled with its cost"""
    bl_idname = "render.ssr_compare"
    bl_label = "Compare Reflections"

    def run(self, context):
        scene = context.scene
        sheet, labels, problems = compare_modes(scene, render_request(scene), **_baseline_choices(scene))
        _show_in_image_editors(context, publish_image(SHEET_IMAGE, sheet))
        if problems:
            self.report({"WARNING"}, f"{'; '.join(labels)} ({'; '.join(problems)})")
        else:
            self.report({"INFO"}, "; ".join(labels))
        return {"FINISHED"}


class RENDER_OT_ssr_apply_preset(bpy.types.Operator):
    """Set every SSR setting to a named preset (draft: fastest, high: closest to the reference)"""
    bl_idname = "render.ssr_apply_preset"
    bl_label = "Apply SSR Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: bpy.props.EnumProperty(name="Preset", items=[(name, name.title(), "") for name in PRESETS])

    def execute(self, context):
        values = preset(self.preset)
        for spec in SETTINGS_SCHEMA:
            setattr(context.scene.ssr, spec.name, getattr(values, spec.name))
        return {"FINISHED"}


class RENDER_OT_ssr_setup_compositor(_ReportsErrors, bpy.types.Operator):
    """Make the compositor output the "SSR Result" image, so F12 and compositing work on it"""
    bl_idname = "render.ssr_setup_compositor"
    bl_label = "Composite SSR Result"
    bl_options = {"REGISTER", "UNDO"}

    def run(self, context):
        image = bpy.data.images.get(RESULT_IMAGE)
        if image is None:
            raise SSRError(f"no '{RESULT_IMAGE}' image yet: render an SSR frame first")
        tree = setup_compositor(context.scene, image)
        self.report({"INFO"}, f"compositor '{tree.name}' outputs '{RESULT_IMAGE}'")
        return {"FINISHED"}


classes = (RENDER_OT_ssr_render_frame, RENDER_OT_ssr_render_animation, RENDER_OT_ssr_compare,
           RENDER_OT_ssr_apply_preset, RENDER_OT_ssr_setup_compositor)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
    forget_last_result()
    release_passes()  # the compiled GPU shaders of the chain
