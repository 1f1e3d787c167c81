"""Viewport overlay: the last "SSR Result" drawn over the 3D view when the SSR
tab's "Show in Viewport" is on. In camera view it fills the camera frame;
otherwise it is a thumbnail in the lower left corner.

GPU objects are made only while drawing, so registering needs no GPU context.
"""
import bpy
import gpu
from bpy_extras.view3d_utils import location_3d_to_region_2d
from gpu_extras.presets import draw_texture_2d

from ..blender.result_image import RESULT_IMAGE

THUMBNAIL_FRACTION = 0.3  # of the region's width, outside camera view

_handle = None


def _camera_frame(context, camera):
    """(x, y, width, height) of the camera frame in region pixels, or None when it is behind the view."""
    frame = [camera.matrix_world @ corner for corner in camera.data.view_frame(scene=context.scene)]
    points = [location_3d_to_region_2d(context.region, context.region_data, corner) for corner in frame]
    if any(point is None for point in points):
        return None
    xs, ys = [p.x for p in points], [p.y for p in points]
    return min(xs), min(ys), max(xs) - min(xs), max(ys) - min(ys)


def _placement(context, image):
    scene = context.scene
    if context.region_data.view_perspective == "CAMERA" and scene.camera is not None:
        return _camera_frame(context, scene.camera)
    width = context.region.width * THUMBNAIL_FRACTION
    return 10.0, 10.0, width, width * image.size[1] / max(image.size[0], 1)


def draw_overlay():
    context = bpy.context
    settings = getattr(context.scene, "ssr", None)
    image = bpy.data.images.get(RESULT_IMAGE)
    if settings is None or not settings.show_overlay or image is None or not image.has_data:
        return
    placement = _placement(context, image)
    if placement is None:
        return
    x, y, width, height = placement
    gpu.state.blend_set("ALPHA")
    draw_texture_2d(gpu.texture.from_image(image), (x, y), width, height,
                    is_scene_linear_with_rec709_srgb_target=True)
    gpu.state.blend_set("NONE")


def is_registered():
    return _handle is not None


def register():
    global _handle
    _handle = bpy.types.SpaceView3D.draw_handler_add(draw_overlay, (), "WINDOW", "POST_PIXEL")


def unregister():
    global _handle
    bpy.types.SpaceView3D.draw_handler_remove(_handle, "WINDOW")
    _handle = None
