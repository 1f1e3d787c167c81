"""The layers of a frame as the user sees them: the passes EXR's channels and the debug views.

The chain's layers are declared with the passes that write them (gpu_passes.chain_layers);
the inputs' below. A frame's layers are read back once (read_layers) into arrays at the
frame's resolution, image order: traced-resolution resources are scaled up nearest, one ray
texel over its quad.
"""
import numpy as np

from .gpu_backend import download
from .gpu_passes import DEBUG_VIEWS, Layer, chain_layers

# (resource, Layer) of the chain's inputs, read from the RenderPasses of the same name unless
# the chain wrote the resource itself (the analytic lamp split's).
INPUT_LAYERS = (
    ("combined", Layer("Combined", "RGBA")),
    ("depth", Layer("Depth", "Z")),
    ("normal", Layer("Normal", "XYZ")),
    ("roughness", Layer("Roughness", "V")),
    ("specular_color", Layer("Specular Color", "RGB")),
    ("f0", Layer("F0", "RGB")),
    ("specular_direct", Layer("Specular Direct", "RGB")),
    ("specular_indirect", Layer("Specular Indirect", "RGB")),
)
_INPUT_RESOURCES = {resource for resource, _ in INPUT_LAYERS}
DEBUG_VIEW_LAYERS = {layer.view.identifier: layer.name for _, layer in chain_layers() if layer.view is not None}
assert list(DEBUG_VIEW_LAYERS) == [identifier for identifier, _, _ in DEBUG_VIEWS[1:]]


def frame_layers():
    """[(resource, Layer)] of a frame: the inputs, then the chain's."""
    return [*INPUT_LAYERS, *chain_layers()]


def upsample_nearest(array, scale, shape):
    """Full-resolution view of a traced-resolution buffer (image order): each texel covers its quad."""
    if scale == 1:
        return array
    bottom_up = array[::-1].repeat(scale, axis=0).repeat(scale, axis=1)[:shape[0], :shape[1]]
    return np.ascontiguousarray(bottom_up[::-1])


def read_layers(passes, outputs=None, names=None):
    """{layer name: (H, W, C) float32} of one frame: PASSES (RenderPasses) and the chain's
    OUTPUTS (ChainOutputs; None without SSR), only the layers NAMES where given. A layer
    whose resource nothing wrote (SSR off, its pass skipped, an input not captured) is zero."""
    height, width = passes.depth.shape
    textures = outputs.textures if outputs is not None else {}
    downloaded, layers = {}, {}
    for resource, layer in frame_layers():
        if names is not None and layer.name not in names:
            continue
        texture = textures.get(resource)
        if texture is not None:
            if resource not in downloaded:
                pixels = download(texture)
                downloaded[resource] = upsample_nearest(pixels, -(-width // texture.width), (height, width))
            pixels = downloaded[resource]
        elif resource in _INPUT_RESOURCES:
            pixels = getattr(passes, resource)
            if pixels is None:  # not captured (a viewport capture's F0)
                pixels = np.zeros((height, width, 4), np.float32)
            pixels = pixels[..., None] if pixels.ndim == 2 else pixels
        else:
            pixels = np.zeros((height, width, 4), np.float32)
        array = pixels[..., list(layer.channel_indices)]
        layers[layer.name] = layer.convert(array) if layer.convert is not None else array
    return layers


def exr_channels(layers):
    """{"Layer.C": (H, W)} of LAYERS (read_layers), channels in the layers' order."""
    components = {layer.name: layer.components for _, layer in frame_layers()}
    return {f"{name}.{component}": array[..., index]
            for name, array in layers.items() for index, component in enumerate(components[name])}


def debug_pixels(final, layers, debug_view):
    """(H, W, 4) of one debug view (gpu_passes.DEBUG_VIEWS): FINAL, or its layer from LAYERS
    (read_layers) with one channel as grey, two as red and green."""
    if debug_view == "FINAL":
        return final
    array = layers[DEBUG_VIEW_LAYERS[debug_view]]
    channels = [array[..., index] for index in range(array.shape[-1])]
    zeros, ones = np.zeros_like(channels[0], np.float32), np.ones_like(channels[0], np.float32)
    rgb = channels * 3 if len(channels) == 1 else channels + [zeros] * (3 - len(channels))
    return np.stack(rgb + [ones], axis=-1).astype(np.float32)
