"""The SSR tab's "Live" toggle: live SSR in one 3D View (live_session.LiveSession).

A modal operator owns the session: its window timer ticks it, Esc or the toggle
stops it. A POST_PIXEL handler draws the session's image over its region and times the draw. A
depsgraph handler reports scene changes (LiveSession.scene_updated), which drop the view's
history (the session absorbs those its own capture makes). Opening a file stops it.
Stopping removes the timer; unregistering stops the session and removes every handler.
"""
import time

import bpy
import gpu
from gpu_extras.presets import draw_texture_2d

from ..blender.viewport_capture import window_region
from ..core.errors import SSRError
from .live_session import TICK_INTERVAL_S, LiveSession

_session = None
_timer = None          # (window manager, timer) of the running session
_draw_handle = None


def running_session():
    return _session


def draw_session(session):
    """Draw SESSION's image over the bound framebuffer's region-sized viewport, if it has one."""
    texture = session.texture
    if texture is None:
        return False
    draw_image(texture, session.region.width, session.region.height)
    return True


def draw_image(texture, width, height):
    """Draw the display-encoded TEXTURE (live_session.LiveSession.texture) over WIDTH x HEIGHT pixels
    of the bound framebuffer."""
    gpu.state.blend_set("NONE")
    draw_texture_2d(texture, (0, 0), width, height)


def draw_live():
    session = _session
    if session is not None and bpy.context.region == session.region:
        started = time.perf_counter()
        draw_session(session)
        session.draw_ms = (time.perf_counter() - started) * 1000.0


@bpy.app.handlers.persistent  # app handlers are dropped on file load unless persistent
def _scene_changed(scene, depsgraph):
    session = _session
    if session is not None:
        session.scene_updated(scene, all(isinstance(update.id, bpy.types.Scene) for update in depsgraph.updates))


@bpy.app.handlers.persistent
def _file_loading(*_):
    stop()


def start(session, window_manager, window):
    global _session, _timer
    stop()
    _session = session
    _timer = (window_manager, window_manager.event_timer_add(TICK_INTERVAL_S, window=window))


def stop():
    """End the running session, if any, and free what it holds."""
    global _session, _timer
    if _timer is not None:
        window_manager, timer = _timer
        window_manager.event_timer_remove(timer)
        _timer = None
    if _session is not None:
        _session.release()
        _session = None


class VIEW3D_OT_ssr_live(bpy.types.Operator):
    bl_idname = "view3d.ssr_live"
    bl_label = "Live SSR"
    bl_description = ("SSR over this 3D View, refined while the view holds still (Material Preview or Rendered "
                      "shading with EEVEE). Esc or the button again stops it")

    @classmethod
    def poll(cls, context):
        return context.area is not None and context.area.type == "VIEW_3D"

    def invoke(self, context, event):
        if _session is not None:
            stop()
            return {"FINISHED"}
        session = LiveSession(context.space_data, window_region(context.area), context.space_data.region_3d)
        problem = session.problem(context.scene)
        if problem is not None:
            self.report({"WARNING"}, problem)
            return {"CANCELLED"}
        start(session, context.window_manager, context.window)
        self._session = session
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        session = self._session
        if _session is not session:  # stopped by the toggle, a file load or unregistering
            return {"FINISHED"}
        if event.type == "ESC":
            self._end(context)
            return {"FINISHED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            changed = session.tick(context.scene)
        except SSRError as error:
            self.report({"WARNING"}, f"live SSR stopped: {error}")
            self._end(context)
            return {"CANCELLED"}
        if changed:
            self._redraw(context)
        return {"PASS_THROUGH"}

    def _end(self, context):
        stop()
        self._redraw(context)

    @staticmethod
    def _redraw(context):
        for area in context.screen.areas if context.screen else ():
            if area.type == "VIEW_3D":
                area.tag_redraw()


classes = (VIEW3D_OT_ssr_live,)


def register():
    global _draw_handle
    for cls in classes:
        bpy.utils.register_class(cls)
    _draw_handle = bpy.types.SpaceView3D.draw_handler_add(draw_live, (), "WINDOW", "POST_PIXEL")
    bpy.app.handlers.depsgraph_update_post.append(_scene_changed)
    bpy.app.handlers.load_pre.append(_file_loading)


def unregister():
    global _draw_handle
    stop()
    bpy.app.handlers.load_pre.remove(_file_loading)
    bpy.app.handlers.depsgraph_update_post.remove(_scene_changed)
    bpy.types.SpaceView3D.draw_handler_remove(_draw_handle, "WINDOW")
    _draw_handle = None
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
