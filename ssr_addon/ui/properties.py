"""The add-on's scene settings: one PropertyGroup, `Scene.ssr`.

The chain's fields are generated from core.settings.SETTINGS_SCHEMA, so a field added
to the schema appears here, in the panels and in `chain_settings` with no edit
to this file. The rest are UI-only choices (comparison mode, debug view...); the
debug views are those the chain's passes declare (core.gpu_passes.DEBUG_VIEWS).
"""
import bpy

from ..blender.baselines import COMPARISON_MODES
from ..blender.result_image import republish_last_result
from ..core.gpu_passes import DEBUG_VIEWS
from ..core.settings import SETTINGS_SCHEMA, ChainSettings

ENABLE_FIELD = "use_ssr"  # drawn in the panel header, not in a group
DEFAULT_GROUP = "tracing"  # for schema fields without metadata["group"]
GROUP_ORDER = ("tracing", "resolve", "temporal", "fading", "fallback", "lamps")


def _schema_property(spec):
    """The bpy property of one schema field, typed by its default value; enums list metadata["items"],
    other strings are text the schema checks."""
    metadata = spec.metadata
    common = {"name": spec.name.replace("_", " ").title(), "description": metadata.get("description") or "",
              "default": spec.default}
    limits = {key: metadata[key] for key in ("min", "max") if metadata.get(key) is not None}
    kind = type(spec.default)
    if kind is bool:
        return bpy.props.BoolProperty(**common)
    if kind is int:
        return bpy.props.IntProperty(**common, **limits)
    if kind is float:
        return bpy.props.FloatProperty(**common, **limits, precision=3)
    if kind is str and metadata.get("items"):
        return bpy.props.EnumProperty(items=metadata["items"], **common)
    if kind is str:
        return bpy.props.StringProperty(**common)
    raise TypeError(f"setting {spec.name!r}: no Blender property for a {kind.__name__} without items")


def _redraw_views(self, context):
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


def _republish_result(self, context):
    republish_last_result(self.debug_view)


def _is_mesh(self, obj):
    return obj.type == "MESH"


UI_PROPERTIES = {
    "comparison_mode": bpy.props.EnumProperty(
        name="Comparison", items=COMPARISON_MODES, default="SSR",
        description="Which reflections the SSR buttons render"),
    "debug_view": bpy.props.EnumProperty(
        name="Debug View", items=DEBUG_VIEWS, default="FINAL",
        description="What the SSR Result image shows", update=_republish_result),
    "probe_object": bpy.props.PointerProperty(
        name="Cubemap Centre", type=bpy.types.Object,
        description="Object the reflection cubemap is captured around (it never reflects itself); "
                    "empty: free space over the middle of the scene, at the camera's height"),
    "planar_object": bpy.props.PointerProperty(
        name="Mirror Plane", type=bpy.types.Object, poll=_is_mesh,
        description="Flat mesh the planar reflection is rendered for; empty: the largest flat mesh"),
    "live_resolution": bpy.props.IntProperty(
        name="Live Resolution", default=50, min=10, max=100, subtype="PERCENTAGE",
        description="Resolution live SSR captures and traces the 3D View at, as a share of the view's size"),
    "show_overlay": bpy.props.BoolProperty(
        name="Show in Viewport", default=False, update=_redraw_views,
        description="Draw the last SSR result over the 3D view (in the camera frame in camera view)"),
}


def settings_group(schema):
    """A PropertyGroup class with one property per SCHEMA field, plus the UI properties."""
    clashes = set(UI_PROPERTIES) & {spec.name for spec in schema}
    if clashes:
        raise TypeError(f"UI properties shadow chain settings: {', '.join(sorted(clashes))}")
    return type("SSRSceneSettings", (bpy.types.PropertyGroup,), {
        "__doc__": "Screen-space reflection settings of a scene",
        "__annotations__": {**{spec.name: _schema_property(spec) for spec in schema}, **UI_PROPERTIES},
    })


SSRSceneSettings = settings_group(SETTINGS_SCHEMA)


def chain_settings(scene_settings):
    """The ChainSettings the PropertyGroup holds."""
    return ChainSettings(**{spec.name: getattr(scene_settings, spec.name) for spec in SETTINGS_SCHEMA})


def grouped_fields(schema=SETTINGS_SCHEMA):
    """{group: [field name, ...]} of the schema fields the panels draw, groups in display order."""
    groups = {}
    for spec in schema:
        if spec.name != ENABLE_FIELD:
            groups.setdefault(spec.metadata.get("group") or DEFAULT_GROUP, []).append(spec.name)
    known = [group for group in GROUP_ORDER if group in groups]
    return {group: groups[group] for group in known + sorted(set(groups) - set(known))}


def register():
    bpy.utils.register_class(SSRSceneSettings)
    bpy.types.Scene.ssr = bpy.props.PointerProperty(type=SSRSceneSettings)


def unregister():
    del bpy.types.Scene.ssr
    bpy.utils.unregister_class(SSRSceneSettings)
