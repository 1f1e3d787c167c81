"""GPU resources of every pass, declared with GPUShaderCreateInfo (EEVEE's naming:
`*_tx` sampled textures, `*_img` outputs, `params` the shared uniform block).

GLSL files in gpu_shaders/ hold only functions and main(); `*_lib.glsl` files
are shared preludes.
"""
import functools
import os

import gpu
import numpy as np

from .gpu_backend import FullscreenPass

SHADER_DIR = os.path.join(os.path.dirname(__file__), "gpu_shaders")


@functools.lru_cache(maxsize=None)
def glsl_source(name):
    with open(os.path.join(SHADER_DIR, name), encoding="utf-8") as source:
        return source.read()


def _pass(name, samplers, outputs):
    """A full-screen pass reading SAMPLERS and writing OUTPUTS, with the shared params block."""
    def declare(info):
        info.uniform_buf(0, "SSRParams", "params")
        for slot, sampler in enumerate(samplers):
            info.sampler(slot, "FLOAT_2D", sampler)
        for slot, output in enumerate(outputs):
            info.fragment_out(slot, "VEC4", output)
    source = glsl_source("common_lib.glsl") + glsl_source(f"{name}.glsl")
    return FullscreenPass(name, source, declare, typedefs=glsl_source("ssr_params_lib.glsl"))


# name: (sampled textures, outputs)
PASS_RESOURCES = {
    "trace_linear": (("depth_tx", "normal_tx", "roughness_tx"), ("hit_img",)),
    "resolve": (("hit_tx", "radiance_tx", "roughness_tx"), ("reflection_img",)),
    "composite": (("combined_tx", "specular_color_tx", "specular_indirect_tx", "reflection_tx"), ("final_img",)),
}


@functools.lru_cache(maxsize=None)
def get_pass(name):
    """The compiled pass, built once per process (GPU context) and reused every frame."""
    samplers, outputs = PASS_RESOURCES[name]
    return _pass(name, samplers, outputs)


def release_passes():
    """Drop the compiled shaders (on add-on unregister)."""
    get_pass.cache_clear()


def pack_params(view_to_clip, world_to_view, size, clip_start, clip_end, settings):
    """The std140 bytes of SSRParams (see ssr_params_lib.glsl) as a GPU uniform buffer."""
    width, height = size
    def column_major(matrix):
        return np.asarray(matrix, dtype=np.float32).T.ravel()
    values = np.concatenate([
        column_major(view_to_clip),
        column_major(np.linalg.inv(np.asarray(view_to_clip, dtype=np.float64))),
        column_major(world_to_view),
        [width, height, 1.0 / width, 1.0 / height],
        [clip_start, clip_end, 0.0, 0.0],
        [settings.thickness, settings.max_distance, settings.trace_stride, settings.trace_steps],
        [settings.refine_steps, settings.border_fade, settings.camera_facing_fade, settings.max_roughness],
    ]).astype(np.float32)
    return gpu.types.GPUUniformBuf(gpu.types.Buffer("FLOAT", values.size, values))
