"""Panels: "Screen-Space Reflections" in the Render properties and the "SSR" tab
of the 3D Viewport sidebar.

The settings sub-panels are generated from the schema's groups
(settings.grouped_fields), so a new schema field needs no edit here.
"""
import bpy

from ..core.settings import PRESETS
from . import live
from .properties import ENABLE_FIELD, grouped_fields


class SSRRenderPanelMixin:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {"BLENDER_EEVEE", "CYCLES"}

    @classmethod
    def unavailable_reason(cls, scene):
        """Why SSR cannot run on SCENE as it is, or None."""
        if scene.render.engine not in cls.COMPAT_ENGINES:
            return "Needs the EEVEE or Cycles render engine"
        if scene.camera is None:
            return "Needs an active scene camera"
        return None


class RENDER_PT_ssr(SSRRenderPanelMixin, bpy.types.Panel):
    bl_label = "Screen-Space Reflections"

    def draw_header(self, context):
        self.layout.active = self.unavailable_reason(context.scene) is None
        self.layout.prop(context.scene.ssr, ENABLE_FIELD, text="")

    def draw(self, context):
        reason = self.unavailable_reason(context.scene)
        if reason is not None:
            self.layout.label(text=reason, icon="ERROR")
        row = self.layout.row(align=True)
        row.active = reason is None
        row.label(text="Preset")
        for name in PRESETS:
            row.operator("render.ssr_apply_preset", text=name.title()).preset = name


def _draw_group(self, context):
    layout = self.layout
    layout.use_property_split = True
    layout.use_property_decorate = False
    settings = context.scene.ssr
    layout.active = settings.use_ssr and self.unavailable_reason(context.scene) is None
    for name in self.fields:
        layout.prop(settings, name)


def _group_panel(group, fields):
    """A sub-panel of RENDER_PT_ssr drawing FIELDS."""
    return type(f"RENDER_PT_ssr_{group}", (SSRRenderPanelMixin, bpy.types.Panel), {
        "bl_label": group.replace("_", " ").title(),
        "bl_parent_id": RENDER_PT_ssr.__name__,
        "bl_options": {"DEFAULT_CLOSED"},
        "fields": tuple(fields),
        "draw": _draw_group,
    })


class VIEW3D_PT_ssr(bpy.types.Panel):
    bl_label = "Screen-Space Reflections"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "SSR"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        settings = scene.ssr
        reason = SSRRenderPanelMixin.unavailable_reason(scene)
        if reason is not None:
            layout.label(text=reason, icon="ERROR")
        layout.row().prop(settings, "comparison_mode", expand=True)
        if settings.comparison_mode == "CUBEMAP":
            layout.prop(settings, "probe_object")
        elif settings.comparison_mode == "PLANAR":
            layout.prop(settings, "planar_object")
        layout.prop(settings, "debug_view")
        column = layout.column(align=True)
        column.enabled = reason is None
        column.operator("render.ssr_render_frame", icon="RENDER_STILL")
        column.operator("render.ssr_render_animation", icon="RENDER_ANIMATION")
        column.operator("render.ssr_compare", icon="IMAGE_REFERENCE")
        layout.operator("render.ssr_setup_compositor", icon="NODE_COMPOSITING")
        layout.prop(settings, "show_overlay")
        session = live.running_session()
        row = layout.row(align=True)
        row.operator("view3d.ssr_live", text="Live", icon="PAUSE" if session else "PLAY", depress=session is not None)
        row.prop(settings, "live_resolution", text="")
        if session is not None:
            layout.label(text=session.status)


def panel_classes():
    """Every panel class, parents first, the group sub-panels built from the current schema."""
    return (RENDER_PT_ssr, *(_group_panel(group, fields) for group, fields in grouped_fields().items()),
            VIEW3D_PT_ssr)


_registered = []


def register():
    for cls in panel_classes():
        bpy.utils.register_class(cls)
        _registered.append(cls)


def unregister():
    while _registered:
        bpy.utils.unregister_class(_registered.pop())
