"""One Hi-Z ray's walk through the min-depth pyramid, for the deck's "Hierarchical ray
trace" slides: recorded from the tracer's own GLSL (the `hiz_walk` pass replays
hiz_march_lib.glsl's march_hiz through its HIZ_WALK_VISIT hook). slides/hiz_diagram.py draws it.

No bpy.context here: `hiz_walk` takes ChainInputs (ChainInputs.from_passes of an
EEVEE render, or synthetic textures) and the chain's settings, builds the min-depth
pyramid as the chain does and runs the pass. `draw_hiz_walk` writes the diagram.

Coordinates: `pixel` and `hit_pixel` are (column, row) of the image, row 0 at the
top, as numpy arrays in the rest of the add-on; a visit's `cell` is the texel of its
pyramid level the shader read, x right and y up from the bottom row (OpenGL's order,
cell (x, y) of level L covers pixels x * 2^L .. (x + 1) * 2^L - 1, likewise in y).
"""
from dataclasses import dataclass, replace

import numpy as np

import os

from ssr_addon.core.chain import chain_params, frame_context
from ssr_addon.core.frame_sequence import Iteration
from ssr_addon.core.gpu_backend import TexturePool, download, empty_texture
from ssr_addon.core.gpu_passes import COMMON_LIBRARIES, HIZ_DOWNSAMPLE, PYRAMID_PACK, GPUPass, Output
from ssr_addon.core.pyramids import build_pyramid
from ssr_addon.core.uniforms import HISTORY_MODES, HIZ_VISITS

OUTCOMES = {code: name for name, code in HIZ_VISITS.items()}  # a visit's HIZ_VISIT_* code, by name
WALK_ENDS = {"no ray": -1, "miss": 0, "hit": 1}  # how the walk ended: hiz_walk.glsl's WALK_END_*
# One ray's Hi-Z march replayed visit by visit, for the deck's diagram.
HIZ_WALK = GPUPass(
    "hiz_walk", "hiz_walk.glsl", samplers=("depth_tx", "normal_tx", "hiz_tx"),
    outputs=(Output("walk_img"), Output("walk_span_img"), Output("walk_ray_img")),
    libraries=(*COMMON_LIBRARIES, "screen_ray_lib.glsl", "surface_ray_lib.glsl", "hiz_walk_lib.glsl",
               "hiz_march_lib.glsl"),
    defines=tuple((f"WALK_END_{name.upper().replace(' ', '_')}", f"{code}.0") for name, code in WALK_ENDS.items()),
    push_constants=(("IVEC2", "walk_pixel"),), directory=os.path.join(os.path.dirname(__file__), "shaders"))


@dataclass(frozen=True)
class Visit:
    """One iteration of march_hiz: the cell it looked at and what it made of it."""
    iteration: int      # 1, 2, ...: the trace pass counts these (ray_stats_img.y)
    level: int          # pyramid level: the cell is 2^level pixels square
    cell: tuple         # (x, y) texel of that level, y up (see the module docstring)
    outcome: str        # "skip" (in front of the whole cell: climb), "descend", "behind" (passes behind), "hit"
    t: float            # the ray's parameter entering the cell (0: its origin, 1: its far end)
    t_next: float       # ... and leaving it (or the screen's edge)
    ray_depth: tuple    # view depth of the ray at t and at t_next
    cell_depth: float   # the cell's min depth, as the pyramid holds it

    @property
    def size(self):
        return 1 << self.level

    def pixel_bounds(self):
        """(x0, y0, x1, y1): the full-resolution pixels the cell covers, y up, ends exclusive."""
        x, y = self.cell
        return x * self.size, y * self.size, (x + 1) * self.size, (y + 1) * self.size


@dataclass
class HiZWalk:
    """The walk of one pixel's mirror ray, as the Hi-Z tracer takes it."""
    pixel: tuple            # (column, row), row 0 at the top
    size: tuple             # (width, height) of the frame
    status: str             # "hit", "miss" (off screen, or out of iterations) or "no ray"
    visits: list            # Visit, in order
    iterations: int         # what the trace pass counts for this ray (len(visits))
    highest_level: int
    hit_pixel: tuple        # (column, row) the ray hit, None unless status is "hit"
    t_hit: float            # -1 unless hit
    hit_depth: float        # the ray's view depth at the hit
    ray_start_px: tuple     # the ray on screen, y up: start and change up to t = 1 (pixels)
    ray_delta_px: tuple
    pixel_tests: int        # visits of the same march held at level 0: a pixel-by-pixel walk
    linear_hit_pixel: tuple  # where that walk ends (None: no hit); the Hi-Z walk should agree
    max_iterations: int     # the cap the walk ran under (settings.hiz_max_iterations)
    thickness: float
    clip_end: float

    def screen_distance(self, t):
        """Pixels along the ray's screen path from its origin up to T."""
        return float(np.hypot(*self.ray_delta_px)) * np.asarray(t, np.float64)

    def position_px(self, t):
        """Screen position (x, y up) at T, in pixels."""
        return np.asarray(self.ray_start_px) + np.asarray(self.ray_delta_px) * t

    def ending(self):
        """How the march ended, in words."""
        if self.status != "miss":
            return {"hit": f"hit at pixel {self.hit_pixel}", "no ray": "no ray from this pixel"}[self.status]
        if self.iterations >= self.max_iterations:
            return f"miss: out of iterations ({self.max_iterations})"
        return "miss: nothing hit on screen"

    def summary(self):
        """The numbers a caption needs."""
        caption = (f"{self.iterations} cell visits instead of {self.pixel_tests} pixel tests"
                   if self.status != "no ray" else "no ray from this pixel")
        return {"status": self.status, "iterations": self.iterations, "highest_level": self.highest_level,
                "hit_pixel": self.hit_pixel, "pixel_tests": self.pixel_tests, "caption": caption}


def _image_pixel(gl_pixel, height):
    return (int(gl_pixel[0]), height - 1 - int(gl_pixel[1]))


def _run_walk(inputs, settings, hiz_tx, hiz_rects, pixel_gl, length):
    """Draw the hiz_walk pass into LENGTH x 1 targets; returns (walk, span, ray) arrays (LENGTH, 4)."""
    frame = frame_context(inputs, replace(settings, half_resolution=False), state=None)
    frame.hiz_rects, frame.color_rects = hiz_rects, [(0, 0, *frame.size)]  # no colour pyramid: the walk reads none
    iteration = Iteration(sample_index=0, quad_phase=0, noise_seed=0, read_slot=None, write_slot=0)
    params = chain_params(frame, iteration, HISTORY_MODES["none"], frame.world_to_clip)
    targets = [empty_texture((length, 1)) for _ in range(3)]
    textures = inputs.textures
    HIZ_WALK.draw(targets, samplers=(("depth_tx", textures["depth"]), ("normal_tx", textures["normal"]),
                                     ("hiz_tx", hiz_tx)),
                  uniform_blocks=(("params", params),), constants=(("walk_pixel", pixel_gl),))
    return [download(target)[0] for target in targets]


def hiz_walk(inputs, settings, pixel, pool=None, pyramid=None):
    """Record the Hi-Z march of PIXEL's mirror ray (column, row; row 0 at the top).

    INPUTS: ChainInputs (only its depth and normal, the camera and clip range are read);
    SETTINGS: ChainSettings (thickness, max_distance, hiz_max_iterations; Hi-Z is used
    whatever use_hiz says). The ray is trace.glsl's with mirror directions: whatever the
    pixel's roughness, and whether or not the ray budget would make it expensive.
    The min-depth pyramid is built as the chain builds it (pyramids.build_pyramid), in POOL's
    textures (a fresh pool by default), unless PYRAMID gives one built so: (atlas, rectangles).
    Returns a HiZWalk.
    """
    width, height = inputs.size
    column, row = map(int, pixel)
    if not (0 <= column < width and 0 <= row < height):
        raise ValueError(f"pixel {pixel} is off the {width}x{height} frame")
    pixel_gl = (column, height - 1 - row)
    settings = replace(settings, use_hiz=True)
    hiz_tx, hiz_rects = pyramid or build_pyramid(inputs.textures["depth"], HIZ_DOWNSAMPLE, PYRAMID_PACK,
                                                 pool or TexturePool())

    cap = int(settings.hiz_max_iterations)
    walk, span, ray = _run_walk(inputs, settings, hiz_tx, hiz_rects, pixel_gl, cap + 1)
    end = next(index for index in range(cap + 1) if walk[index, 0] < 0)
    end_walk, end_span, end_ray = walk[end], span[end], ray[end]
    visits = [Visit(iteration=index + 1, level=int(walk[index, 0]), cell=(int(walk[index, 1]), int(walk[index, 2])),
                    outcome=OUTCOMES[int(walk[index, 3])], t=float(span[index, 0]), t_next=float(span[index, 1]),
                    ray_depth=(float(span[index, 2]), float(span[index, 3])), cell_depth=float(ray[index, 0]))
              for index in range(end)]
    code = int(end_walk[3])
    status = {code: name for name, code in WALK_ENDS.items()}[code]
    hit = status == "hit"

    # The same march held at level 0 (a one-level pyramid: it never climbs) visits every
    # pixel the ray crosses up to the hit: what a linear pixel-by-pixel walk tests.
    pixel_tests, linear_hit_pixel = 0, None
    if status != "no ray":
        longest = width + height + 2  # a line crosses at most this many pixels
        linear_settings = replace(settings, hiz_max_iterations=longest)
        linear_walk, linear_span, _ = _run_walk(inputs, linear_settings, hiz_tx, hiz_rects[:1], pixel_gl,
                                                longest + 1)
        linear_end = next(index for index in range(longest + 1) if linear_walk[index, 0] < 0)
        pixel_tests = int(linear_span[linear_end, 2])
        if int(linear_walk[linear_end, 3]) == WALK_ENDS["hit"]:
            linear_hit_pixel = _image_pixel(linear_walk[linear_end, 1:3], height)

    return HiZWalk(
        pixel=(column, row), size=(width, height), status=status, visits=visits,
        iterations=int(end_span[2]) if status != "no ray" else 0,
        highest_level=int(end_span[3]) if status != "no ray" else 0,
        hit_pixel=_image_pixel(end_walk[1:3], height) if hit else None,
        t_hit=float(end_span[0]) if hit else -1.0, hit_depth=float(end_span[1]) if hit else 0.0,
        ray_start_px=(float(end_ray[0]), float(end_ray[1])), ray_delta_px=(float(end_ray[2]), float(end_ray[3])),
        pixel_tests=pixel_tests, linear_hit_pixel=linear_hit_pixel, max_iterations=cap,
        thickness=float(settings.thickness), clip_end=float(inputs.clip_end))


def most_instructive_walk(inputs, settings, pixels):
    """Of the walks of PIXELS (as hiz_walk's), the hit that saves the most pixel tests, or None
    where none hits: a caller picks candidates (smooth surfaces, say) and gets the ray that shows
    the hierarchy at its best. The pyramid is built once for all of them."""
    pyramid = build_pyramid(inputs.textures["depth"], HIZ_DOWNSAMPLE, PYRAMID_PACK, TexturePool())
    walks = [hiz_walk(inputs, settings, pixel, pyramid=pyramid) for pixel in pixels]
    hits = [walk for walk in walks if walk.status == "hit"]
    return max(hits, key=lambda walk: (walk.pixel_tests - walk.iterations, walk.highest_level), default=None)
