"""The labelled comparison sheet: tiles side by side, each under lines of text drawn with
Blender's UI font on the GPU."""
import blf
import gpu
import numpy as np
from mathutils import Matrix

from ..core.gpu_backend import download
from .gpu_context import ensure_backend

SHEET_IMAGE = "SSR Comparison"


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
