"""GPU resources of every pass, declared with GPUShaderCreateInfo (EEVEE's naming:
`*_tx` sampled textures, `*_img` outputs, `params` the shared uniform block).

GLSL files in gpu_shaders/ hold only functions and main(); `*_lib.glsl` files
are shared preludes, listed per pass below.
"""
import functools
import os
from dataclasses import dataclass

from .frame_sequence import MAX_ITERATIONS
from .gpu_backend import FullscreenPass
from .gpu_params import glsl_struct, lamp_block_glsl

SHADER_DIR = os.path.join(os.path.dirname(__file__), "gpu_shaders")
DFG_SIZE = 32  # the FG table's resolution in n.v and roughness
DFG_SAMPLES = 4096  # points per texel: within 0.015 of a 32768-point table even at grazing angles
# Share of the GGX lobe's visible normals, the outermost, that rays never sample (trace.glsl);
# the resolve bounds each ray's cone by the lobe that is left.
LOBE_TAIL = 0.02
CONVERGENCE_TILE = 16  # pixels: each tile this size counts alike in the convergence check
LUT_SIZE = 65                             # display LUT lattice points per channel (display_lut.py)
# Stops of scene-linear light the display LUT spans (its first point is 0). 1.0, where the
# Standard view clips, falls on a lattice point: interpolating across that bend costs 5 steps.
LUT_LOG2_MIN, LUT_LOG2_MAX = -15.0, 9.0


@dataclass(frozen=True)
class PassDeclaration:
    source: str                 # the pass's GLSL file
    samplers: tuple             # 2D textures; volume_samplers are 3D
    outputs: tuple
    libraries: tuple = ("common_lib.glsl",)
    defines: tuple = ()         # (name, value)
    push_constants: tuple = ()  # (type, name)
    uses_params: bool = True
    volume_samplers: tuple = ()
    uses_lamp_block: bool = False  # reads `lamp_block` (gpu_params.LAMP_BLOCK) instead of `params`


_TRACE_LIBRARIES = ("common_lib.glsl", "screen_ray_lib.glsl", "surface_ray_lib.glsl", "linear_march_lib.glsl",
                    "hiz_march_lib.glsl", "ggx_lib.glsl")

# Where a pyramid level reads its source and draws itself (chain.build_pyramid).
_PYRAMID_LEVEL = (("IVEC2", "source_offset"), ("IVEC2", "source_size"), ("IVEC2", "level_offset"))

PASSES = {
    "copy": PassDeclaration("copy.glsl", ("source_tx",), ("copy_img",), libraries=(), uses_params=False),
    "hiz_downsample": PassDeclaration("pyramid_downsample.glsl", ("source_tx",), ("level_img",),
                                      libraries=(), defines=(("REDUCE_MIN", ""),), push_constants=_PYRAMID_LEVEL,
                                      uses_params=False),
    "color_downsample": PassDeclaration("pyramid_downsample.glsl", ("source_tx",), ("level_img",),
                                        libraries=(), push_constants=_PYRAMID_LEVEL, uses_params=False),
    "pyramid_pack": PassDeclaration("pyramid_pack.glsl", ("level_tx",), ("atlas_img",), libraries=(),
                                    push_constants=(("IVEC2", "level_offset"),), uses_params=False),
    "trace": PassDeclaration("trace.glsl", ("depth_tx", "normal_tx", "roughness_tx", "hiz_tx"),
                             ("ray_hit_img", "ray_dir_img", "ray_stats_img"), libraries=_TRACE_LIBRARIES,
                             defines=(("LOBE_TAIL", repr(LOBE_TAIL)),)),
    # One ray's Hi-Z march replayed visit by visit, for the deck's diagram (hiz_walk.py).
    "hiz_walk": PassDeclaration("hiz_walk.glsl", ("depth_tx", "normal_tx", "hiz_tx"),
                                ("walk_img", "walk_span_img", "walk_ray_img"),
                                libraries=("common_lib.glsl", "screen_ray_lib.glsl", "surface_ray_lib.glsl",
                                           "hiz_walk_lib.glsl", "hiz_march_lib.glsl"),
                                push_constants=(("IVEC2", "walk_pixel"),)),
    "resolve": PassDeclaration("resolve.glsl", ("ray_hit_tx", "ray_dir_tx", "depth_tx", "normal_tx",
                                                "roughness_tx", "color_tx", "history_count_tx"),
                               ("reflection_img", "reflection_hit_img"),
                               libraries=("common_lib.glsl", "ggx_lib.glsl", "history_lib.glsl"),
                               defines=(("LOBE_TAIL", repr(LOBE_TAIL)),)),
    "resolve_upscale": PassDeclaration("resolve_upscale.glsl", ("reflection_tx", "reflection_hit_tx"),
                                       ("reflection_img", "reflection_hit_img"), libraries=()),
    "denoise_spatial": PassDeclaration("denoise_spatial.glsl", ("reflection_tx", "reflection_hit_tx", "depth_tx",
                                                                "normal_tx", "roughness_tx", "history_count_tx"),
                                       ("filtered_img",), libraries=("common_lib.glsl", "ggx_lib.glsl",
                                                                     "history_lib.glsl")),
    "temporal": PassDeclaration("temporal.glsl", ("reflection_tx", "reflection_hit_tx", "depth_tx", "motion_tx",
                                                  "radiance_tx", "previous_radiance_tx", "history_tx",
                                                  "history_count_tx"),
                                ("filtered_img", "count_img"),
                                defines=(("STATIC_HISTORY_FRAMES", f"{MAX_ITERATIONS}.0"),)),
    "dfg_table": PassDeclaration("dfg_table.glsl", (), ("dfg_img",), libraries=("common_lib.glsl", "ggx_lib.glsl"),
                                 defines=(("DFG_SIZE", str(DFG_SIZE)), ("DFG_SAMPLES", str(DFG_SAMPLES)))),
    "lamp_split": PassDeclaration("lamp_split.glsl", ("depth_tx", "normal_tx", "roughness_tx", "albedo_tx",
                                                      "specular_light_tx", "shadow_tx"),
                                  ("specular_direct_img", "specular_indirect_img"), libraries=("ggx_lib.glsl",),
                                  uses_params=False, uses_lamp_block=True),
    "composite": PassDeclaration("composite.glsl", ("combined_tx", "specular_color_tx", "specular_indirect_tx",
                                                    "reflection_tx", "f0_tx", "dfg_tx", "depth_tx", "normal_tx",
                                                    "roughness_tx"), ("final_img",)),
    "convergence_tiles": PassDeclaration("convergence_tiles.glsl", ("before_tx", "after_tx"), ("tiles_img",),
                                         libraries=(), defines=(("CONVERGENCE_TILE", str(CONVERGENCE_TILE)),),
                                         uses_params=False),
    "display_transform": PassDeclaration("display_transform.glsl", ("image_tx",), ("display_img",), libraries=(),
                                         defines=(("LUT_SIZE", f"{LUT_SIZE}.0"), ("LUT_LOG2_MIN", repr(LUT_LOG2_MIN)),
                                                  ("LUT_LOG2_MAX", repr(LUT_LOG2_MAX))),
                                         push_constants=(("INT", "use_view_transform"), ("FLOAT", "exposure_scale")),
                                         uses_params=False,
                                         volume_samplers=("lut_tx",)),
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
        if declaration.uses_lamp_block:
            info.uniform_buf(0, "LampBlock", "lamp_block")
        for name, value in declaration.defines:
            info.define(name, value)
        for kind, constant in declaration.push_constants:
            info.push_constant(kind, constant)
        for slot, sampler in enumerate(declaration.samplers):
            info.sampler(slot, "FLOAT_2D", sampler)
        for slot, sampler in enumerate(declaration.volume_samplers, len(declaration.samplers)):
            info.sampler(slot, "FLOAT_3D", sampler)
        for slot, output in enumerate(declaration.outputs):
            info.fragment_out(slot, "VEC4", output)
    source = "".join(glsl_source(library) for library in declaration.libraries) + glsl_source(declaration.source)
    typedefs = (glsl_struct() if declaration.uses_params else "") + \
        (lamp_block_glsl() if declaration.uses_lamp_block else "")
    return FullscreenPass(name, source, declare, typedefs=typedefs)


def release_passes():
    """Drop the compiled shaders (on add-on unregister)."""
    get_pass.cache_clear()
