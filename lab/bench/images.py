"""Reading frames back (EXR channels, RGB layers) and the display transform of scene-linear images."""
import os

import numpy as np
import OpenImageIO as oiio

from ssr_addon.core.errors import SSRError


def read_channels(path):
    """{channel name: (H, W) float32} of a single-part EXR as run_render writes it."""
    source = oiio.ImageInput.open(path)
    if source is None:
        raise SSRError(f"cannot read {path}: {oiio.geterror()}")
    try:
        spec = source.spec()
        pixels = source.read_image(0, 0, 0, spec.nchannels, "float")
    finally:
        source.close()
    return {name: np.asarray(pixels[..., index]) for index, name in enumerate(spec.channelnames)}


def layer_rgb(channels, layer=None, components="RGB"):
    prefix = f"{layer}." if layer else ""
    return np.stack([channels[f"{prefix}{c}"] for c in components], axis=-1)


def render_folder_frame(folder):
    """frame -> (final RGB, passes channels) of a run_render output folder."""
    def frame_images(frame):
        stem = os.path.join(folder, f"frame_{frame:04d}")
        return layer_rgb(read_channels(stem + ".exr")), read_channels(stem + ".passes.exr")
    return frame_images


def display(linear):
    """Scene-linear RGB to [0, 1]: Reinhard tone map, then the sRGB transfer curve.

    PSNR, SSIM and the contact sheet use it; FLIP takes the linear images (HDR-FLIP).
    """
    mapped = np.maximum(linear, 0.0) / (1.0 + np.maximum(linear, 0.0))
    return np.where(mapped <= 0.0031308, 12.92 * mapped, 1.055 * np.power(mapped, 1 / 2.4) - 0.055)
