"""GPU resources of every pass, declared with GPUShaderCreateInfo (EEVEE's naming:
`*_tx` sampled textures, `*_img` outputs, `params` the shared uniform block).

GLSL files in gpu_shaders/ hold only functions and main(); `*_lib.glsl` files
are shared preludes, listed per pass below.
"""
import functools
import os
from dataclasses import dataclass

import gpu
import numpy as np

from .gpu_backend import FullscreenPass

SHADER_DIR = os.path.join(os.path.dirname(__file__), "gpu_shaders")
MAX_PYRAMID_LEVELS = 16  # ssr_params_lib.glsl
DFG_SIZE = 32  # the FG table's resolution in n.v and roughness
DFG_SAMPLES = 4096  # points per texel: within 0.015 of a 32768-point table even at grazing angles


@dataclass(frozen=True)
class PassDeclaration:
    source: str                 # the pass's GLSL file
    samplers: tuple
    outputs: tuple
    libraries: tuple = ("common_lib.glsl",)
    defines: tuple = ()         # (name, value)
    push_constants: tuple = ()  # (type, name)
    uses_params: bool = True


_TRACE_LIBRARIES = ("common_lib.glsl", "screen_ray_lib.glsl", "linear_march_lib.glsl",
                    "hiz_march_lib.glsl", "ggx_lib.glsl")

PASSES = {
    "copy": PassDeclaration("copy.glsl", ("source_tx",), ("copy_img",), libraries=(), uses_params=False),
    "hiz_downsample": PassDeclaration("pyramid_downsample.glsl", ("source_tx",), ("level_img",),
                                      libraries=(), defines=(("REDUCE_MIN", ""),), uses_params=False),
    "color_downsample": PassDeclaration("pyramid_downsample.glsl", ("source_tx",), ("level_img",),
                                        libraries=(), uses_params=False),
    "pyramid_pack": PassDeclaration("pyramid_pack.glsl", ("level_tx",), ("atlas_img",), libraries=(),
                                    push_constants=(("IVEC2", "level_offset"),), uses_params=False),
    "trace": PassDeclaration("trace.glsl", ("depth_tx", "normal_tx", "roughness_tx", "hiz_tx"),
                             ("ray_hit_img", "ray_dir_img", "ray_stats_img"), libraries=_TRACE_LIBRARIES),
    "resolve": PassDeclaration("resolve.glsl", ("ray_hit_tx", "ray_dir_tx", "depth_tx", "normal_tx",
                                                "roughness_tx", "color_tx"),
                               ("reflection_img", "reflection_hit_img"),
                               libraries=("common_lib.glsl", "ggx_lib.glsl")),
    "temporal": PassDeclaration("temporal.glsl", ("reflection_tx", "reflection_hit_tx", "depth_tx", "motion_tx",
                                                  "history_tx", "history_count_tx"),
                                ("filtered_img", "count_img")),
    "dfg_table": PassDeclaration("dfg_table.glsl", (), ("dfg_img",), libraries=("common_lib.glsl", "ggx_lib.glsl"),
                                 defines=(("DFG_SIZE", str(DFG_SIZE)), ("DFG_SAMPLES", str(DFG_SAMPLES)))),
    "composite": PassDeclaration("composite.glsl", ("combined_tx", "specular_color_tx", "specular_indirect_tx",
                                                    "reflection_tx", "f0_tx", "dfg_tx", "depth_tx", "normal_tx",
                                                    "roughness_tx"), ("final_img",)),
}


@functools.lru_cache(maxsize=None)
def glsl_source(name):
    with open(os.path.join(SHADER_DIR, name), encoding="utf-8") as source:
        return source.read()


@functools.lru_cache(maxsize=None)
def get_pass(name):
    """The compiled pass, built once per process (GPU context) and reused every frame."""
    declaration = PASSES[name]

    def declare(info):
        if declaration.uses_params:
            info.uniform_buf(0, "SSRParams", "params")
        for name, value in declaration.defines:
            info.define(name, value)
        for kind, constant in declaration.push_constants:
            info.push_constant(kind, constant)
        for slot, sampler in enumerate(declaration.samplers):
            info.sampler(slot, "FLOAT_2D", sampler)
        for slot, output in enumerate(declaration.outputs):
            info.fragment_out(slot, "VEC4", output)
    source = "".join(glsl_source(library) for library in declaration.libraries) + glsl_source(declaration.source)
    typedefs = glsl_source("ssr_params_lib.glsl") if declaration.uses_params else ""
    return FullscreenPass(name, source, declare, typedefs=typedefs)


def release_passes():
    """Drop the compiled shaders (on add-on unregister)."""
    get_pass.cache_clear()


def _column_major(matrix):
    return np.asarray(matrix, dtype=np.float32).T.ravel()


def _level_rects(rects):
    packed = np.zeros((MAX_PYRAMID_LEVELS, 4), np.float32)
    packed[:len(rects)] = rects
    return packed.ravel()


def pack_params(camera, previous_world_to_clip, size, trace_size, frame_index, ray_budget,
                hiz_rects, color_rects, history_mode, history_frames, settings):
    """The std140 bytes of SSRParams (see ssr_params_lib.glsl) as a GPU uniform buffer.

    camera: (world_to_view, view_to_clip, clip_start, clip_end); ray_budget:
    (expensive roughness threshold, tie fraction); history_mode: 0 none, 1 clamped
    (animation), 2 unclamped (a still's iterations); history_frames: most frames
    the temporal filter averages.
    """
    world_to_view, view_to_clip, clip_start, clip_end = camera
    width, height = size
    values = np.concatenate([
        _column_major(view_to_clip),
        _column_major(np.linalg.inv(np.asarray(view_to_clip, dtype=np.float64))),
        _column_major(world_to_view),
        _column_major(np.linalg.inv(np.asarray(world_to_view, dtype=np.float64))),
        _column_major(previous_world_to_clip),
        [width, height, 1.0 / width, 1.0 / height],
        [trace_size[0], trace_size[1], 2.0 if settings.half_resolution else 1.0, 0.0],
        [clip_start, clip_end, 0.0, 0.0],
        [frame_index, ray_budget[0], ray_budget[1], len(hiz_rects) if settings.use_hiz else 0],
        [settings.thickness, settings.max_distance, settings.trace_stride, settings.trace_steps],
        [settings.refine_steps, settings.border_fade, settings.camera_facing_fade, settings.max_roughness],
        [float(settings.use_importance_sampling), settings.resolve_samples, float(settings.use_cone_filter),
         settings.hiz_max_iterations],
        [history_frames, float(settings.temporal_reprojection == "hit"), history_mode,
         len(color_rects)],
        _level_rects(hiz_rects),
        _level_rects(color_rects),
    ]).astype(np.float32)
    return gpu.types.GPUUniformBuf(gpu.types.Buffer("FLOAT", values.size, values))
