"""Every GPU pass, declared once in the style of EEVEE's create-infos: its GLSL file, the
resources it reads and writes, the stage it is timed as and the layers of the passes EXR
(and debug views) its outputs hold.

Names follow EEVEE's: a sampler `X_tx` reads the chain resource X, an output `X_img` writes
it (chain.FrameRun binds them by name), `params` is the shared uniform block (uniforms.PARAMS).
GLSL files hold only functions and main(); `*_lib.glsl` files are shared preludes. From one
declaration the chain runs the pass, the stage timer names it, the passes EXR lays out its
layers (layers.py) and the debug views are offered (DEBUG_VIEWS). Adding a pass is one GLSL
file and one declaration, placed in FRAME_PASSES or ITERATION_PASSES where it runs.
"""
import functools
import os
from dataclasses import dataclass

import numpy as np

from .captures import PLANE_NORMAL_COS, PLANE_TOLERANCE_PX
from .frame_sequence import MAX_ITERATIONS
from .ggx import LAMP_MIN_ALPHA, MIN_ALPHA
from .gpu_backend import FullscreenPass, empty_texture
from .uniforms import glsl_struct, lamp_block_glsl

SHADER_DIR = os.path.join(os.path.dirname(__file__), "shaders")
DFG_SIZE = 32  # the FG table's resolution in n.v and roughness
DFG_SAMPLES = 4096  # points per texel: within 0.015 of a 32768-point table even at grazing angles
# Share of the GGX lobe's visible normals, the outermost, that rays never sample (trace.glsl);
# the resolve bounds each ray's cone by the lobe that is left.
LOBE_TAIL = 0.02
CONVERGENCE_TILE = 16  # pixels: each tile this size counts alike in the convergence check
LUT_SIZE = 65  # display LUT lattice points per channel (blender/colour_management.py bakes it)
# Stops of scene-linear light the display LUT spans (its first point is 0). 1.0, where the
# Standard view clips, falls on a lattice point: interpolating across that bend costs 5 steps.
LUT_LOG2_MIN, LUT_LOG2_MAX = -15.0, 9.0
# The camera and helpers every params pass shares; the defines a library is compiled with.
COMMON_LIBRARIES = ("view_lib.glsl", "common_lib.glsl")
LIBRARY_DEFINES = {"ggx_lib.glsl": (("MIN_ALPHA", repr(MIN_ALPHA)), ("LOBE_TAIL", repr(LOBE_TAIL)))}


@dataclass(frozen=True)
class DebugView:
    """A choice of the Debug View setting: the layer it is declared on, shown as an image."""
    identifier: str
    label: str
    description: str


@dataclass(frozen=True)
class Layer:
    """A layer of the passes EXR: CHANNELS of its resource, one per letter of COMPONENTS
    (default: the first ones), through CONVERT (numpy) where given; VIEW offers it as a debug view."""
    name: str
    components: str
    channels: tuple = None
    convert: object = None
    view: DebugView = None

    @property
    def channel_indices(self):
        return self.channels if self.channels is not None else tuple(range(len(self.components)))


@dataclass(frozen=True)
class Output:
    """An output `X_img` of a pass, writing resource X. SIZE: "frame", "trace" (one ray per
    traced texel), "resolve" (where the resolve shades) or a fixed (width, height). HISTORY: the
    sampler that reads its value from the iteration before (it then takes turns between two
    textures, so a pass can read the old value while writing the new one)."""
    name: str
    size: object = "frame"
    channels: int = 4
    history: str = None
    layers: tuple = ()

    @property
    def resource(self):
        return self.name[:-len("_img")]


def _always(frame):
    return True


@dataclass(frozen=True, eq=False)
class GPUPass:
    """One fragment shader drawn over its whole target (a full-screen triangle).

    SAMPLERS read resources by name (`X_tx` reads X); RUNS(frame) says whether it runs in a frame
    (chain.FrameContext), and SKIPPED which resource stands in for each of its outputs when it
    does not; PLACEHOLDERS, for outputs its readers then leave unread, which texture is bound
    in their place (the frame then has no such resource: its layers read zero). STAGE names its
    time in a StageTimer (None: a helper draw its caller times)."""
    name: str
    source: str
    stage: str = None
    samplers: tuple = ()
    outputs: tuple = ()
    libraries: tuple = COMMON_LIBRARIES
    defines: tuple = ()            # (name, value)
    push_constants: tuple = ()     # (type, name)
    uniform_block: str = "params"  # "params", "lamp_block" (uniforms.LAMP_BLOCK) or None
    volume_samplers: tuple = ()    # 3D textures
    runs: object = _always
    skipped: tuple = ()            # (resource, the resource that stands in for it)
    placeholders: tuple = ()       # (resource, a texture bound for it that nothing reads): not produced
    directory: str = SHADER_DIR

    def draw(self, targets, samplers=(), uniform_blocks=(), constants=(), region=None):
        """Draw into TARGETS (FullscreenPass.draw), compiling the shader on first use."""
        compiled(self).draw(targets, samplers=samplers, uniform_blocks=uniform_blocks, constants=constants,
                            region=region)

    def glsl(self):
        """The fragment source: the libraries (the pass's own folder first, then the core's), then its file."""
        return "".join(_glsl_source(self.directory, name) for name in (*self.libraries, self.source))


@functools.lru_cache(maxsize=None)
def _glsl_source(directory, name):
    path = os.path.join(directory, name)
    if not os.path.isfile(path):
        path = os.path.join(SHADER_DIR, name)
    with open(path, encoding="utf-8") as source:
        return source.read()


_compiled = {}


def compiled(gpu_pass):
    """The pass's shader, built once per process (GPU context) and reused every frame."""
    shader = _compiled.get(gpu_pass)
    if shader is None:
        def declare(info):
            if gpu_pass.uniform_block == "params":
                info.uniform_buf(0, "SSRParams", "params")
            elif gpu_pass.uniform_block == "lamp_block":
                info.uniform_buf(0, "LampBlock", "lamp_block")
            library_defines = (define for library in gpu_pass.libraries for define in LIBRARY_DEFINES.get(library, ()))
            for name, value in (*library_defines, *gpu_pass.defines):
                info.define(name, value)
            for kind, constant in gpu_pass.push_constants:
                info.push_constant(kind, constant)
            for slot, sampler in enumerate(gpu_pass.samplers):
                info.sampler(slot, "FLOAT_2D", sampler)
            for slot, sampler in enumerate(gpu_pass.volume_samplers, len(gpu_pass.samplers)):
                info.sampler(slot, "FLOAT_3D", sampler)
            for slot, output in enumerate(gpu_pass.outputs):
                info.fragment_out(slot, "VEC4", output.name)
        typedefs = {"params": glsl_struct, "lamp_block": lamp_block_glsl}.get(gpu_pass.uniform_block, str)()
        shader = _compiled[gpu_pass] = FullscreenPass(gpu_pass.name, gpu_pass.glsl(), declare, typedefs=typedefs)
    return shader


def release_passes():
    """Drop the compiled shaders and the tables drawn with them (on add-on unregister)."""
    _compiled.clear()
    dfg_table.cache_clear()


def history_weight(count):
    """Share of each pixel that came from history, 1 - 1 / frames accumulated."""
    return 1.0 - 1.0 / np.maximum(count, 1.0)


# --- the chain's passes, in the order of the slides -------------------------------------------------------------

_TRACE_LIBRARIES = (*COMMON_LIBRARIES, "screen_ray_lib.glsl", "surface_ray_lib.glsl", "linear_march_lib.glsl",
                    "hiz_march_lib.glsl", "ggx_lib.glsl", "ray_pdf_lib.glsl")
# Where a pyramid level reads its source and draws itself (pyramids.build_pyramid).
_PYRAMID_LEVEL = (("IVEC2", "source_offset"), ("IVEC2", "source_size"), ("IVEC2", "level_offset"))


def _resolves_at_half(frame):
    return frame.resolve_size != frame.size


LAMP_SPLIT = GPUPass(
    "lamp_split", "lamp_split.glsl", stage="lamp_split",
    samplers=("depth_tx", "normal_tx", "roughness_tx", "dfg_tx", "specular_light_tx", "shadow_tx"),
    outputs=(Output("specular_direct_img"), Output("specular_indirect_img")),
    libraries=("view_lib.glsl", "ggx_lib.glsl", "dfg_lib.glsl"), defines=(("LAMP_MIN_ALPHA", repr(LAMP_MIN_ALPHA)),),
    uniform_block="lamp_block", runs=lambda frame: frame.inputs.lamps is not None)
HIZ_DOWNSAMPLE = GPUPass("hiz_downsample", "pyramid_downsample.glsl", stage="hiz", samplers=("source_tx",),
                         outputs=(Output("level_img", channels=1),), libraries=(), defines=(("REDUCE_MIN", ""),),
                         push_constants=_PYRAMID_LEVEL, uniform_block=None)
COLOR_DOWNSAMPLE = GPUPass("color_downsample", "pyramid_downsample.glsl", stage="color_pyramid",
                           samplers=("source_tx",), outputs=(Output("level_img"),), libraries=(),
                           push_constants=_PYRAMID_LEVEL, uniform_block=None)
PYRAMID_PACK = GPUPass("pyramid_pack", "pyramid_pack.glsl", samplers=("level_tx",), outputs=(Output("atlas_img"),),
                       libraries=(), push_constants=(("IVEC2", "level_offset"),), uniform_block=None)
TRACE = GPUPass(
    "trace", "trace.glsl", stage="trace",
    samplers=("depth_tx", "normal_tx", "roughness_tx", "hiz_tx"),
    outputs=(Output("ray_hit_img", size="trace", layers=(
                 Layer("SSR Hit", "UV", view=DebugView("HIT_UV", "Hit UV", "Screen position each ray hit "
                                                                           "(red: x, green: y)")),
                 Layer("SSR Ray PDF", "V", channels=(2,)))),
             Output("ray_dir_img", size="trace", layers=(Layer("SSR Hit Distance", "V", channels=(3,)),)),
             Output("ray_stats_img", size="trace", layers=(
                 Layer("SSR Ray Class", "V", channels=(0,), view=DebugView(
                     "RAY_CLASS", "Ray Class",
                     "Which tracer each pixel's ray took: 0 none, 1 cheap linear march, 2 expensive Hi-Z")),
                 Layer("SSR HiZ Level", "V", channels=(2,), view=DebugView(
                     "HIZ_LEVEL", "Hi-Z Level", "Coarsest Hi-Z pyramid level each ray reached")),
                 Layer("SSR Iterations", "V", channels=(1,), view=DebugView(
                     "ITERATIONS", "Iterations", "March steps each pixel's ray took (the last trace iteration)"))))),
    libraries=_TRACE_LIBRARIES)


def _traces_sharp_rays(frame):
    """use_sharp_rays with half-resolution rays resolved at full resolution: the smoothest pixels trace
    their own too."""
    settings = frame.settings
    return settings.use_sharp_rays and settings.half_resolution and settings.sharp_roughness > 0.0 \
        and not _resolves_at_half(frame)


TRACE_SHARP = GPUPass(
    "trace_sharp", "trace.glsl", stage="trace",
    samplers=("depth_tx", "normal_tx", "roughness_tx", "hiz_tx"),
    outputs=(Output("sharp_ray_hit_img"), Output("sharp_ray_dir_img")),
    libraries=_TRACE_LIBRARIES, defines=(("SHARP_RAYS", ""),),
    runs=_traces_sharp_rays, placeholders=(("sharp_ray_hit", "ray_hit"), ("sharp_ray_dir", "ray_dir")))
# The screen a capture's rays are marched across (screen_ray_lib.glsl).
_CAPTURE_SCREEN = (("SCREEN_VIEW_TO_CLIP", "params.capture_view_to_clip"), ("SCREEN_SIZE", "params.capture_size"),
                   ("SCREEN_DEPTH_TX", "capture_depth_tx"))
PLANAR_TRACE = GPUPass(
    "planar_trace", "planar_trace.glsl", stage="planar",
    samplers=("ray_hit_tx", "ray_dir_tx", "ray_stats_tx", "depth_tx", "normal_tx", "roughness_tx",
              "history_record_tx", "capture_depth_tx", "capture_normal_tx", "capture_color_tx"),
    outputs=(Output("planar_hit_img", size="trace", layers=(Layer("SSR Planar Hit", "RGBA"),)),
             Output("ray_outcome_img", size="trace", layers=(
                 Layer("SSR Resolved By", "V", channels=(3,), view=DebugView(
                     "RESOLVED_BY", "Resolved By",
                     "Which level resolved each pixel's ray: 1 screen, 2 guard band, 3 planar capture, "
                     "4 depth cube map; and why the rest fell to the probes/world: 5 left the frame, 6 passed "
                     "behind what it shows, 7 escaped; 0 no ray")),))),
    libraries=(*COMMON_LIBRARIES, "screen_ray_lib.glsl", "linear_march_lib.glsl", "ggx_lib.glsl",
               "history_lib.glsl"),
    defines=(*_CAPTURE_SCREEN, ("PLANE_TOLERANCE_PX", repr(PLANE_TOLERANCE_PX)),
             ("PLANE_NORMAL_COS", repr(PLANE_NORMAL_COS))),
    runs=lambda frame: frame.inputs.capture is not None,
    skipped=(("ray_outcome", "ray_stats"),), placeholders=(("planar_hit", "ray_hit"),))
CUBE_TRACE = GPUPass(
    "cube_trace", "cube_trace.glsl", stage="cube",
    samplers=("ray_hit_tx", "ray_dir_tx", "planar_hit_tx", "ray_outcome_tx", "depth_tx", "normal_tx", "roughness_tx",
              "history_record_tx", "cube_depth_tx", "cube_color_tx"),
    outputs=(Output("capture_hit_img", size="trace", layers=(Layer("SSR Capture Hit", "RGBA"),)),
             Output("ray_outcome_img", size="trace")),
    libraries=(*COMMON_LIBRARIES, "ggx_lib.glsl", "history_lib.glsl"),
    runs=lambda frame: frame.inputs.cube is not None, skipped=(("capture_hit", "planar_hit"),))
RESOLVE = GPUPass(
    "resolve", "resolve.glsl", stage="resolve",
    samplers=("ray_hit_tx", "ray_dir_tx", "sharp_ray_hit_tx", "sharp_ray_dir_tx", "depth_tx", "normal_tx",
              "roughness_tx", "color_tx", "history_record_tx", "capture_hit_tx"),
    outputs=(Output("resolved_img", size="resolve", layers=(Layer("SSR Resolve", "RGBA"),)),
             Output("reflection_hit_img", size="resolve")),
    libraries=(*COMMON_LIBRARIES, "ggx_lib.glsl", "ray_pdf_lib.glsl", "history_lib.glsl"))
RESOLVE_UPSCALE = GPUPass("resolve_upscale", "resolve_upscale.glsl", stage="resolve",
                          samplers=("resolved_tx", "reflection_hit_tx"),
                          outputs=(Output("resolved_img"), Output("reflection_hit_img")), libraries=(),
                          runs=_resolves_at_half)
DENOISE_SPATIAL = GPUPass(
    "denoise_spatial", "denoise_spatial.glsl", stage="spatial",
    samplers=("resolved_tx", "reflection_hit_tx", "depth_tx", "normal_tx", "roughness_tx", "history_record_tx"),
    outputs=(Output("spatial_img", layers=(Layer("SSR Spatial", "RGBA"),)),),
    libraries=(*COMMON_LIBRARIES, "ggx_lib.glsl", "history_lib.glsl"),
    runs=lambda frame: frame.settings.use_spatial_filter, skipped=(("spatial", "resolved"),))
TEMPORAL = GPUPass(
    "temporal", "temporal.glsl", stage="temporal",
    samplers=("spatial_tx", "reflection_hit_tx", "depth_tx", "normal_tx", "roughness_tx", "motion_tx",
              "radiance_tx", "previous_radiance_tx", "history_tx", "history_record_tx", "history_moments_tx"),
    outputs=(Output("reflection_img", history="history_tx", layers=(
                 Layer("SSR Reflection", "RGB", view=DebugView("REFLECTION", "Reflection",
                                                               "Reflected radiance alone")),
                 Layer("SSR Confidence", "V", channels=(3,), view=DebugView(
                     "CONFIDENCE", "Confidence",
                     "How much of each pixel's reflection came from a ray hit (white: all)")))),
             Output("history_record_img", history="history_record_tx", layers=(
                 Layer("SSR History Weight", "V", channels=(0,), convert=history_weight),)),
             Output("history_moments_img", history="history_moments_tx")),
    defines=(("STATIC_HISTORY_FRAMES", f"{MAX_ITERATIONS}.0"),),
    runs=lambda frame: frame.settings.use_temporal, skipped=(("reflection", "spatial"),))
DFG_TABLE = GPUPass("dfg_table", "dfg_table.glsl", outputs=(Output("dfg_img", size=(DFG_SIZE, DFG_SIZE)),),
                    libraries=("ggx_lib.glsl",), uniform_block=None,
                    defines=(("DFG_SIZE", str(DFG_SIZE)), ("DFG_SAMPLES", str(DFG_SAMPLES))))


@functools.lru_cache(maxsize=1)
def dfg_table():
    """The FG table as a texture, drawn once per process (it depends on nothing but GGX)."""
    texture = empty_texture(DFG_TABLE.outputs[0].size)
    DFG_TABLE.draw([texture])
    return texture


COMPOSITE = GPUPass(
    "composite", "composite.glsl", stage="composite",
    samplers=("combined_tx", "specular_color_tx", "specular_indirect_tx", "reflection_tx", "f0_tx", "dfg_tx",
              "depth_tx", "normal_tx", "roughness_tx"),
    outputs=(Output("final_img"),), libraries=(*COMMON_LIBRARIES, "dfg_lib.glsl"))
CONVERGENCE_TILES = GPUPass("convergence_tiles", "convergence_tiles.glsl", stage="convergence",
                            samplers=("before_tx", "after_tx"), outputs=(Output("tiles_img"),), libraries=(),
                            defines=(("CONVERGENCE_TILE", str(CONVERGENCE_TILE)),), uniform_block=None)
COPY = GPUPass("copy", "copy.glsl", samplers=("source_tx",), outputs=(Output("copy_img"),), libraries=(),
               uniform_block=None)
DISPLAY_TRANSFORM = GPUPass(
    "display_transform", "display_transform.glsl", samplers=("image_tx",), outputs=(Output("display_img"),),
    libraries=(), defines=(("LUT_SIZE", f"{LUT_SIZE}.0"), ("LUT_LOG2_MIN", repr(LUT_LOG2_MIN)),
                           ("LUT_LOG2_MAX", repr(LUT_LOG2_MAX))),
    push_constants=(("INT", "use_view_transform"), ("FLOAT", "exposure_scale")), uniform_block=None,
    volume_samplers=("lut_tx",))

# What a frame runs, in order (chain.FrameRun): once a frame, once an iteration, once a composite.
FRAME_PASSES = (LAMP_SPLIT,)
ITERATION_PASSES = (TRACE, TRACE_SHARP, PLANAR_TRACE, CUBE_TRACE, RESOLVE, RESOLVE_UPSCALE, DENOISE_SPATIAL, TEMPORAL)
CHAIN_PASSES = (*FRAME_PASSES, HIZ_DOWNSAMPLE, COLOR_DOWNSAMPLE, *ITERATION_PASSES, CONVERGENCE_TILES, COMPOSITE)
# The chain's stages as a StageTimer names them, in order.
CHAIN_STAGES = tuple(dict.fromkeys(gpu_pass.stage for gpu_pass in CHAIN_PASSES if gpu_pass.stage))


def chain_layers():
    """[(resource, Layer)] of every layer the chain's passes declare, in the order they run."""
    layers = {}
    for gpu_pass in CHAIN_PASSES:
        for output in gpu_pass.outputs:
            for layer in output.layers:
                layers.setdefault(layer.name, (output.resource, layer))
    return list(layers.values())


# The Debug View setting's choices: the final image, then every layer declared with a view.
DEBUG_VIEWS = (("FINAL", "Final", "The composited image"),
               *((layer.view.identifier, layer.view.label, layer.view.description)
                 for _, layer in chain_layers() if layer.view is not None))
