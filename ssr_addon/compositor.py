"""SSR results back in Blender: the float "SSR Result" image, its debug views,
the labelled comparison sheet, and a compositor node tree that outputs the image.

Arrays are (H, W, 4) float32 in image order (row 0 at the top), scene linear,
as render_job returns them; Blender images store rows bottom-up.
"""
import blf
import bpy
import gpu
import numpy as np
from mathutils import Matrix

from .gpu_backend import download, ensure_backend
from .render_job import pass_channels

RESULT_IMAGE = "SSR Result"
SHEET_IMAGE = "SSR Comparison"
RESULT_NODE = "SSR Result"  # name of the compositor Image node setup_compositor manages


# The passes-EXR layer (render_job.pass_channels) each debug view shows; FINAL is the image itself.
DEBUG_VIEW_LAYERS = {
    "FINAL": None,
    "REFLECTION": "SSR Reflection",
    "CONFIDENCE": "SSR Confidence",
    "HIT_UV": "SSR Hit",
    "RAY_CLASS": "SSR Ray Class",
    "HIZ_LEVEL": "SSR HiZ Level",
    "ITERATIONS": "SSR Iterations",
}


def debug_pixels(images, debug_view):
    """(H, W, 4) of one debug view: a one-channel layer as grey, two channels as red and green."""
    layer = DEBUG_VIEW_LAYERS[debug_view]
    if layer is None:
        return images["final"]
    channels = [array for name, array in pass_channels(images).items() if name.rpartition(".")[0] == layer]
    zeros, ones = np.zeros_like(channels[0], np.float32), np.ones_like(channels[0], np.float32)
    rgb = channels * 3 if len(channels) == 1 else channels + [zeros] * (3 - len(channels))
    return np.stack(rgb + [ones], axis=-1).astype(np.float32)


# The images of the last render, so a new debug view needs no new render.
_last_images = None


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
    """Show DEBUG_VIEW of a render in the "SSR Result" image and remember the render."""
    global _last_images
    _last_images = images
    return publish_image(RESULT_IMAGE, debug_pixels(images, debug_view))


def republish_last_result(debug_view):
    """Switch the "SSR Result" image to another debug view of the last render, if any."""
    if _last_images is not None:
        publish_image(RESULT_IMAGE, debug_pixels(_last_images, debug_view))


def forget_last_result():
    global _last_images
    _last_images = None


def _text_strip(lines, width, font_size):
    """White text lines on black, (H, width, 4), drawn with Blender's UI font on the GPU."""
    ensure_backend()
    line_height = round(font_size * 1.3)
    height = line_height * len(lines) + 2
    font = 0  # Blender's default UI font
    offscreen = gpu.types.GPUOffScreen(width, height, format="RGBA32F")
    try:
        with offscreen.bind():
            gpu.state.active_framebuffer_get().clear(color=(0.0, 0.0, 0.0, 1.0))
            with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
                gpu.matrix.load_projection_matrix(Matrix.Identity(4))
                # Pixel coordinates, origin at the bottom left.
                gpu.matrix.load_matrix(Matrix.Translation((-1.0, -1.0, 0.0))
                                       @ Matrix.Diagonal((2.0 / width, 2.0 / height, 1.0, 1.0)))
                blf.size(font, font_size)
                blf.color(font, 1.0, 1.0, 1.0, 1.0)
                for index, line in enumerate(lines):
                    blf.position(font, 2, height - (index + 1) * line_height + 2, 0)
                    blf.draw(font, line)
        return download(offscreen.texture_color)
    finally:
        offscreen.free()


def comparison_sheet(tiles):
    """Tiles side by side, each under its label: TILES is [(lines, rgba)], all one size and line count."""
    height, width = tiles[0][1].shape[:2]
    font_size = int(np.clip(width // 9, 8, 28))
    columns = [np.concatenate([_text_strip(lines, width, font_size), rgba.astype(np.float32)], axis=0)
               for lines, rgba in tiles]
    return np.concatenate(columns, axis=1)


def setup_compositor(scene, image):
    """Make the scene's compositor output IMAGE; returns the node tree.

    Where the tree already takes the render from a Render Layers node, those
    links are moved to the image, so the user's own post-processing now works
    on the SSR result; otherwise the image goes straight to the group output.
    """
    tree = scene.compositing_node_group
    if tree is None:
        tree = bpy.data.node_groups.new("SSR Compositing", "CompositorNodeTree")
        scene.compositing_node_group = tree
    source = tree.nodes.get(RESULT_NODE)
    if source is None:
        source = tree.nodes.new("CompositorNodeImage")
        source.name = source.label = RESULT_NODE
    source.image = image
    render_targets = [link.to_socket for link in tree.links
                      if link.from_node.bl_idname == "CompositorNodeRLayers" and link.from_socket.name == "Image"]
    for target in render_targets:
        tree.links.new(source.outputs["Image"], target)
    if not render_targets:
        tree.links.new(source.outputs["Image"], _group_output_socket(tree))
    scene.render.use_compositing = True
    return tree


def _group_output_socket(tree):
    """The first colour output of the tree's Group Output node, both created when missing."""
    if not any(item.item_type == "SOCKET" and item.in_out == "OUTPUT" for item in tree.interface.items_tree):
        tree.interface.new_socket(name="Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    output = next((node for node in tree.nodes if node.bl_idname == "NodeGroupOutput"), None)
    if output is None:
        output = tree.nodes.new("NodeGroupOutput")
    return output.inputs[0]
