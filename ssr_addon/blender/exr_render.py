"""One render of a scene into a multilayer EXR, read back pass by pass with OpenImageIO
(Blender 5 writes one EXR part per pass). Arrays are float32 in image order (row 0 at the top)."""
import os

import bpy
import numpy as np
import OpenImageIO as oiio

from ..core.errors import SSRError


def render_to_exr(scene, path, changes):
    """Render SCENE's current frame into the multilayer EXR PATH (output settings through
    CHANGES); returns its passes by name (read_multilayer_exr)."""
    changes.set_all(scene.render.image_settings, media_type="MULTI_LAYER_IMAGE",
                    file_format="OPEN_EXR_MULTILAYER", color_depth="32", exr_codec="ZIP")
    changes.set_all(scene.render, filepath=path, use_file_extension=False)
    try:
        bpy.ops.render.render(write_still=False, scene=scene.name)
        # Saved from the result rather than by the render: a render that writes its file prints
        # "Saved: ..." for it, which a render farm's worker takes for one of the shot's outputs.
        result = bpy.data.images.get("Render Result")
        if result is not None:
            result.save_render(path, scene=scene)
    except RuntimeError as error:
        raise SSRError(f"render of scene '{scene.name}' failed: {str(error).strip()}") from None
    if not os.path.isfile(path):
        raise SSRError(f"render of scene '{scene.name}' wrote no image (is the render cancelled or empty?)")
    return read_multilayer_exr(path)
def read_multilayer_exr(path):
    """{pass name: (H, W, C) float32} of a Blender multilayer EXR (one part per pass)."""
    source = oiio.ImageInput.open(path)
    if source is None:
        raise SSRError(f"cannot read {path}: {oiio.geterror()}")
    layers = {}
    try:
        subimage = 0
        while source.seek_subimage(subimage, 0):
            spec = source.spec()
            pixels = source.read_image(subimage, 0, 0, spec.nchannels, "float")
            if pixels is None:
                raise SSRError(f"cannot read part {subimage} of {path}: {source.geterror()}")
            name = spec.getattribute("name") or spec.channelnames[0].rpartition(".")[0]
            layers[name.split(".", 1)[-1]] = np.ascontiguousarray(pixels, dtype=np.float32)
            subimage += 1
    finally:
        source.close()
    return layers


def pass_layer(layers, name):
    """Pass NAME of LAYERS (a render's passes by name), or one clear line naming those there are."""
    if name not in layers:
        raise SSRError(f"the render has no '{name}' pass (found: {', '.join(sorted(layers))})")
    return layers[name]
