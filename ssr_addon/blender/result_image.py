"""SSR results back in Blender: the float "SSR Result" image and its debug views.

Arrays are (H, W, 4) float32 in image order (row 0 at the top), scene linear, as
batch.frame returns them; Blender images store rows bottom-up.
"""
import bpy
import numpy as np

from ..core.layers import debug_pixels

RESULT_IMAGE = "SSR Result"

# The last render's (final image, layers), so a new debug view needs no new render.
_last_result = None


def publish_image(name, rgba):
    """Store RGBA in the float, scene-linear image NAME (created or resized as needed)."""
    height, width = rgba.shape[:2]
    image = bpy.data.images.get(name)
    if image is not None and not (image.is_float and image.source == "GENERATED"):
        bpy.data.images.remove(image)  # a loaded or 8-bit image of that name cannot hold the result
        image = None
    if image is None:
        image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    elif tuple(image.size) != (width, height):
        image.scale(width, height)
    image.pixels.foreach_set(np.ascontiguousarray(rgba[::-1], dtype=np.float32).ravel())
    image.update()
    return image


def publish_result(images, debug_view):
    """Show DEBUG_VIEW of a render's IMAGES (batch.frame.FrameImages) in the "SSR Result" image
    and remember them."""
    global _last_result
    _last_result = images.final, images.layers
    return publish_image(RESULT_IMAGE, debug_pixels(*_last_result, debug_view))


def last_result():
    """(final image, layers) of the last render published, or None."""
    return _last_result


def republish_last_result(debug_view):
    """Switch the "SSR Result" image to another debug view of the last render, if any."""
    if _last_result is not None:
        publish_image(RESULT_IMAGE, debug_pixels(*_last_result, debug_view))


def forget_last_result():
    global _last_result
    _last_result = None
