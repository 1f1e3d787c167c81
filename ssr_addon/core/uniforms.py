"""The chain's uniform block `params`: one schema for its GLSL struct and its std140 bytes.

Every parameter a pass reads is a named field here, so a shader says
`params.sample_index`, not `params.frame.x` with the meaning in a comment, and
the Python side packs by name: a field missing from `pack_params` is an error.
"""
import numpy as np

MAX_PYRAMID_LEVELS = 16
# Enumerations the shaders share with Python, each #defined as PREFIX_<NAME> (shader_enums).
# params.ray_sampling: the code of each ChainSettings.ray_sampling.
RAY_SAMPLING_CODES = {"halton": 0, "random": 1, "uniform": 2}
# params.history_mode: what the temporal filter's history is (chain.FrameRun).
HISTORY_MODES = {"none": 0, "animation": 1, "still": 2, "view": 3}
# What one cell visit of the Hi-Z march did (hiz_march_lib.glsl's recording hook).
HIZ_VISITS = {"skip": 1, "descend": 2, "behind": 3, "hit": 4}
# What became of each traced ray (ray_stats_img.w, the "Resolved By" debug view): which level of
# the fallback hierarchy resolved it, or, where none did and the probes/world stand in, why the
# screen could not: its ray left the frame, passed behind what the frame shows, or escaped
# (reached its length or the sky in view).
RAY_OUTCOMES = {"none": 0, "screen": 1, "guard_band": 2, "planar": 3, "cube": 4, "left_frame": 5, "behind": 6,
                "escaped": 7}
# params.capture_levels: a bit for each capture level that ran this frame.
CAPTURE_LEVELS = {"planar": 1, "cube": 2}
# LampData.shape: the emitter of each Lamp.shape (lamp_split.glsl).
LAMP_SHAPES = {"sphere": 0, "facing_disk": 1, "sun": 2, "rect": 3, "ellipse": 4}

# (GLSL type, name, comment); arrays as "vec4[N]". std140 offsets are computed below.
PARAMS_FIELDS = (
    ("mat4", "view_to_clip", "camera projection"),
    ("mat4", "clip_to_view", "its inverse"),
    ("mat4", "world_to_view", "camera view matrix"),
    ("mat4", "view_to_world", "its inverse"),
    ("mat4", "previous_world_to_clip", "last frame's view-projection, for temporal reprojection"),
    ("vec2", "viewport_size", "full resolution in pixels"),
    ("vec2", "pixel_size", "1 / viewport_size"),
    ("vec2", "trace_size", "traced rays along each axis"),
    ("vec4", "frame_rect", "the requested frame within this one, pixels (x0, y0, x1, y1): a guard band around it"),
    ("int", "trace_scale", "pixels per traced ray along each axis (1 or 2)"),
    ("int", "resolve_scale", "pixels per resolved texel along each axis (1, or 2 resolving at the traced size)"),
    ("uint", "sample_index", "this iteration's index in the low-discrepancy sequence"),
    ("int", "quad_phase", "which pixel of each 2x2 quad originates this iteration's ray (0..3)"),
    ("uint", "noise_seed", "changes every iteration: decorrelates the ray-class coin over time"),
    ("float", "clip_start", "camera near clip"),
    ("float", "clip_end", "depth at or past it is background"),
    ("float", "expensive_roughness", "pixels smoother than this get expensive (Hi-Z) rays"),
    ("float", "expensive_tie_fraction", "share of pixels at exactly that roughness that do"),
    ("float", "sharp_roughness", "pixels at most this rough trace a ray of their own every iteration (trace_sharp); "
                                 "-1: none does"),
    ("int", "hiz_levels", "levels in the min-depth pyramid (0: no Hi-Z tracing)"),
    ("int", "hiz_max_iterations", "most cell visits per Hi-Z ray"),
    ("float", "thickness", "assumed depth of every surface, scene units"),
    ("float", "max_distance", "longest ray, scene units"),
    ("float", "trace_stride", "shortest linear-march step, pixels"),
    ("int", "trace_steps", "most linear-march depth tests"),
    ("int", "refine_steps", "binary-search steps after a linear-march hit"),
    ("float", "border_fade", "fade hits this close to where their ray leaves the screen (fraction of it)"),
    ("float", "camera_facing_fade", "fade rays pointing back at the camera"),
    ("float", "max_roughness", "rougher pixels keep the probe/world reflection"),
    ("int", "use_importance_sampling", "GGX lobe samples (1) or mirror directions (0)"),
    ("int", "ray_sampling", "RAY_SAMPLING_* (RAY_SAMPLING_CODES): how lobe directions are drawn"),
    ("int", "resolve_samples", "rays each pixel reuses in the resolve"),
    ("int", "use_cone_filter", "read hits as cones from the colour pyramid"),
    ("int", "color_levels", "levels in the colour pyramid"),
    ("int", "use_firefly_guard", "resolve in tone-mapped space, c / (1 + max(c) / iterations averaged)"),
    ("float", "denoise_radius", "spatial filter radius in pixels at roughness max_roughness"),
    ("int", "reproject_hit", "temporal filter reprojects the hit point (1) or the surface (0)"),
    ("int", "history_mode", "HISTORY_MODE_*: none, an animation's (clipped), a still's own iterations (unclipped), "
                            "a view moved over a still scene (unclipped where a flat glossy reflector moved under "
                            "a pixel)"),
    ("float", "history_frames", "most frames a moving pixel averages"),
    (f"vec4[{MAX_PYRAMID_LEVELS}]", "hiz_level", "min-depth pyramid atlas: x, y offset, width, height"),
    (f"vec4[{MAX_PYRAMID_LEVELS}]", "color_level", "colour pyramid atlas, likewise"),
    ("int", "capture_levels", "CAPTURE_LEVEL_* bits of the captures that ran (resolve reads capture_hit_tx)"),
    ("int", "captures_changed", "the captures are not the last frame's: what they show moved"),
    ("int", "probe_reflection", "the frame's own reflection is a probe's (EEVEE), not a path tracer's: captures "
                                "take the world where rays escape and the shares the screen's fades leave"),
    ("int", "fg_from_specular_color", "no F0 pass (a viewport capture's): FG is the engine's specular colour"),
    ("int", "capture_light_stands", "where the screen and the planar capture hit the same surface, the capture's "
                                    "light stands: it is path traced, the frame is EEVEE's"),
    ("int", "capture_from_this_view", "the planar capture's camera is this view's mirrored: its hits may replace the "
                                      "screen's unchecked (planar_trace.glsl)"),
    ("mat4", "capture_world_to_view", "the planar capture's camera: the frame's mirrored in its plane"),
    ("mat4", "capture_view_to_clip", "its projection"),
    ("vec4", "capture_plane", "the reflector's plane in world space, n.x + d, n towards what it reflects"),
    ("vec2", "capture_size", "the capture's pixels"),
    ("int", "capture_color_levels", "levels in its colour pyramid"),
    (f"vec4[{MAX_PYRAMID_LEVELS}]", "capture_color_level", "its colour pyramid atlas"),
    ("mat4[6]", "cube_world_to_face", "the depth cube map's faces: world to each face camera's view"),
    ("vec4", "cube_centre", "where it was captured (xyz); w: texels along a face's side"),
    ("int", "cube_color_levels", "levels in its colour pyramid (the six faces in a 3 x 2 atlas)"),
    ("int", "cube_steps", "march steps through it per ray"),
    ("float", "cube_reach", "farthest a surface it shows lies from its centre"),
    (f"vec4[{MAX_PYRAMID_LEVELS}]", "cube_color_level", "its colour pyramid atlas"),
)

# Lights of lamp_split=analytic (lamp_split.py, lamp_split.glsl); it refuses a scene with more.
MAX_LAMPS = 64

LAMP_FIELDS = (
    ("vec3", "position", "world position; for a sun, the unit direction towards it"),
    ("int", "shape", "LAMP_SHAPE_* (LAMP_SHAPES)"),
    ("vec3", "radiance", "emitted radiance, specular factor included"),
    ("float", "influence_radius", "local lights fade to nothing at this distance"),
    ("vec3", "x_axis", "the light's local axes in world space (it emits along -z)"),
    ("float", "half_width", "area lights: half the x extent; spheres, disks and suns: the radius"),
    ("vec3", "y_axis", ""),
    ("float", "half_height", "area lights: half the y extent"),
    ("vec3", "z_axis", ""),
    ("float", "spot_mul", "spot cone: smoothstep(0, 1, ellipse * spot_mul + spot_bias), as EEVEE"),
    ("vec2", "spot_size_inv", "spot cone stretch by the object's scale"),
    ("float", "spot_bias", ""),
    ("int", "is_spot", "1 for spot lights"),
)

LAMP_BLOCK_FIELDS = (
    ("mat4", "clip_to_view", "inverse camera projection"),
    ("mat4", "view_to_world", "inverse camera view matrix"),
    ("vec2", "viewport_size", "pixels"),
    ("float", "background_depth", "depth at or past it is the world"),
    ("int", "lamp_count", "lamps in use"),
    ("int", "strata_per_side", "each sampling strategy takes this squared stratified points"),
    (f"LampData[{MAX_LAMPS}]", "lamps", ""),
)

# std140: (base alignment, size) in 4-byte words.
_LAYOUT = {"float": (1, 1), "int": (1, 1), "uint": (1, 1), "vec2": (2, 2), "vec3": (4, 3), "vec4": (4, 4),
           "mat4": (4, 16)}


class Std140Struct:
    """A GLSL struct: its declaration and the std140 bytes of {field: value}, every field required.

    FIELDS are (GLSL type, name, comment); arrays as "vec4[N]" or "Struct[N]" of a struct in
    NESTED; an array of structs may be given fewer than N, the rest left zero. Matrices are
    given in numpy (row-major) convention and stored column-major, as GLSL reads them.
    """

    def __init__(self, name, fields, nested=()):
        self.name, self.fields = name, fields
        self.nested = {struct.name: struct for struct in nested}
        self.offsets, cursor = {}, 0
        for glsl_type, field_name, _ in fields:
            base, _, count = glsl_type.partition("[")
            if base in self.nested:
                alignment, size = 4, self.nested[base].words
            else:
                alignment, size = _LAYOUT[base]
            if count:  # array elements are vec4-aligned
                alignment, size = 4, -(-size // 4) * 4 * int(count.rstrip("]"))
            cursor = -(-cursor // alignment) * alignment
            self.offsets[field_name] = (base, cursor, size)
            cursor += size
        self.words = -(-cursor // 4) * 4

    def glsl(self):
        lines = [f"struct {self.name} {{"]
        for glsl_type, name, comment in self.fields:
            base, _, count = glsl_type.partition("[")
            declaration = f"{base} {name}[{count}" if count else f"{glsl_type} {name}"
            lines.append(f"  {declaration};" + (f" /* {comment} */" if comment else ""))
        lines.append("};")
        return "\n".join(lines) + "\n"

    def pack(self, values):
        words = np.zeros(self.words, np.uint32)
        as_float = words.view(np.float32)
        as_int = words.view(np.int32)
        missing = [name for name in self.offsets if name not in values]
        unknown = [name for name in values if name not in self.offsets]
        if missing or unknown:
            raise KeyError(f"{self.name}: missing {missing}, unknown {unknown}")
        for name, value in values.items():
            base, offset, size = self.offsets[name]
            if base in self.nested:
                struct = self.nested[base]  # its words are a whole number of vec4s: the array stride
                if len(value) * struct.words > size:
                    raise ValueError(f"{self.name}.{name}: {len(value)} elements, room for {size // struct.words}")
                for index, element in enumerate(value):
                    start = offset + index * struct.words
                    words[start:start + struct.words] = struct.pack(element)
            elif base == "mat4":  # column-major, each matrix of an array in turn
                matrices = np.asarray(value, np.float64)
                as_float[offset:offset + size] = np.swapaxes(matrices, -1, -2).ravel() if matrices.ndim >= 2 \
                    else matrices
            elif base == "int":
                as_int[offset] = int(value)
            elif base == "uint":
                words[offset] = int(value) & 0xFFFFFFFF
            else:
                flat = np.asarray(value, np.float64).ravel()
                as_float[offset:offset + flat.size] = flat
        return words


PARAMS = Std140Struct("SSRParams", PARAMS_FIELDS)
LAMP_DATA = Std140Struct("LampData", LAMP_FIELDS)
LAMP_BLOCK = Std140Struct("LampBlock", LAMP_BLOCK_FIELDS, nested=(LAMP_DATA,))


def shader_enums(prefix, codes):
    """#define PREFIX_NAME code for each of CODES ({name: code})."""
    return "".join(f"#define {prefix}_{name.upper()} {code}\n" for name, code in codes.items())


def glsl_struct():
    """The SSRParams struct and the enumerations its fields take, for GPUShaderCreateInfo.typedef_source."""
    return (f"#define MAX_PYRAMID_LEVELS {MAX_PYRAMID_LEVELS}\n" + shader_enums("RAY_SAMPLING", RAY_SAMPLING_CODES)
            + shader_enums("HISTORY_MODE", HISTORY_MODES) + shader_enums("HIZ_VISIT", HIZ_VISITS) + shader_enums("RAY_OUTCOME", RAY_OUTCOMES) + shader_enums("CAPTURE_LEVEL", CAPTURE_LEVELS)
            + PARAMS.glsl())


def lamp_block_glsl():
    """The LampData and LampBlock structs, for GPUShaderCreateInfo.typedef_source."""
    return shader_enums("LAMP_SHAPE", LAMP_SHAPES) + LAMP_DATA.glsl() + LAMP_BLOCK.glsl()


def pack_params(values):
    """The std140 bytes of SSRParams from {field: value}; every field is required."""
    return PARAMS.pack(values)
