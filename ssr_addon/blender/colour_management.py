"""The scene's colour management (view transform, look, exposure, gamma, display): images
written as F12 saves them (write_display_png), and on the GPU, so the live overlay shows what
the 3D View around it shows: exposure as a scale, the rest as a 3D LUT.

Blender's Python API has no GPU colour-management call for a texture, so the LUT is baked
through Blender's own path for saving renders: a lattice of scene-linear colours goes through
`save_render` into a 16-bit PNG and is read back. The lattice is spaced in stops (a log2
shaper), which a filmic curve such as AgX is smooth in; display_transform.glsl applies it.
"""
import os
import tempfile

import bpy
import gpu
import numpy as np
import OpenImageIO as oiio

from ..core.errors import SSRError
from ..core.gpu_passes import DISPLAY_TRANSFORM, LUT_LOG2_MAX, LUT_LOG2_MIN, LUT_SIZE
from .overrides import TemporaryChanges


def write_display_png(path, rgba, scene, color_depth="8"):
    """PNG (8 or 16 bits) through the scene's view transform, look, exposure and gamma (as F12 saves it)."""
    height, width = rgba.shape[:2]
    image = bpy.data.images.new("ssr_display", width, height, alpha=True, float_buffer=True)
    try:
        image.pixels.foreach_set(np.ascontiguousarray(rgba[::-1], dtype=np.float32).ravel())
        with TemporaryChanges() as changes:
            changes.set_all(scene.render.image_settings, media_type="IMAGE", file_format="PNG",
                            color_mode="RGBA", color_depth=color_depth)
            image.save_render(path, scene=scene)
    except RuntimeError as error:
        raise SSRError(f"cannot write {path}: {str(error).strip()}") from None
    finally:
        bpy.data.images.remove(image)


def view_settings_key(scene):
    """What the baked LUT depends on: a change re-bakes it."""
    view, display = scene.view_settings, scene.display_settings
    white_balance = tuple(getattr(view, name, None) for name in
                          ("use_white_balance", "white_balance_temperature", "white_balance_tint"))
    return (display.display_device, view.view_transform, view.look, round(view.gamma, 6),
            view.use_curve_mapping, white_balance)


def lattice_values():
    """Scene-linear value of each lattice point along one channel."""
    values = np.exp2(np.linspace(LUT_LOG2_MIN, LUT_LOG2_MAX, LUT_SIZE))
    values[0] = 0.0
    return values


def blender_display(scene, rgba):
    """RGBA (scene linear, image order) as Blender's colour management shows it in SCENE: written
    undithered through `save_render` into a 16-bit PNG and read back, (H, W, 3) display encoded."""
    with tempfile.TemporaryDirectory(prefix="ssr_display_") as folder:
        path = os.path.join(folder, "display.png")
        with TemporaryChanges() as changes:
            changes.set(scene.render, "dither_intensity", 0.0)  # its noise would be read back
            write_display_png(path, rgba, scene, color_depth="16")
        source = oiio.ImageInput.open(path)
        if source is None:
            raise SSRError(f"cannot read back the colour-managed image: {oiio.geterror()}")
        display = source.read_image("float")
        source.close()
    return np.asarray(display, np.float32)[..., :3]


def bake_display_lut(scene):
    """(LUT_SIZE,) * 3 + (3,) display-encoded colours indexed [blue][green][red], through SCENE's
    colour management at exposure 0."""
    values = lattice_values().astype(np.float32)
    blue, green, red = np.meshgrid(values, values, values, indexing="ij")
    lattice = np.stack([red, green, blue, np.ones_like(red)], axis=-1).reshape(LUT_SIZE * LUT_SIZE, LUT_SIZE, 4)
    with TemporaryChanges() as changes:
        changes.set(scene.view_settings, "exposure", 0.0)  # applied in the shader
        display = blender_display(scene, lattice)
    return display.reshape(LUT_SIZE, LUT_SIZE, LUT_SIZE, 3)


class DisplayTransform:
    """Scene-linear textures to display-encoded ones, re-baking the LUT when the scene's colour
    management changes."""

    def __init__(self):
        self._key = None
        self._lut_tx = None

    def _lut(self, scene):
        key = view_settings_key(scene)
        if key != self._key:
            colours = bake_display_lut(scene)
            rgba = np.concatenate([colours, np.ones(colours.shape[:3] + (1,), np.float32)], axis=-1)
            data = gpu.types.Buffer("FLOAT", rgba.size, np.ascontiguousarray(rgba).ravel())
            self._lut_tx = gpu.types.GPUTexture((LUT_SIZE,) * 3, format="RGBA16F", data=data)
            self._key = key
        return self._lut_tx

    def apply(self, scene, image_tx, pool, view_transform=True):
        """IMAGE_TX (scene linear) as the 3D View would show it; with VIEW_TRANSFORM off, with the
        plain sRGB curve (for data such as the debug views)."""
        target_tx = pool.get("display", (image_tx.width, image_tx.height))
        DISPLAY_TRANSFORM.draw(
            [target_tx], samplers=(("image_tx", image_tx), ("lut_tx", self._lut(scene))),
            constants=(("use_view_transform", int(view_transform)),
                       ("exposure_scale", float(2.0 ** scene.view_settings.exposure))))
        return target_tx

    def release(self):
        self._key = self._lut_tx = None
