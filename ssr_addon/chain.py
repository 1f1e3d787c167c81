"""The SSR chain: a plain function from textures and settings to textures.

No bpy.context here: callers (CLI, operators, tests) hand in GPU textures and
the camera, keep a ChainState between frames (temporal history, reused
textures) and get GPU textures back. Stage timings go into a StageTimer.

Stages, in the order of the slides: Hi-Z pyramid, colour pyramid, ray
generation and tracing (cheap/expensive classes, GGX + Halton, half
resolution), resolve with neighbour reuse and cone filtering, temporal
filter, composite with the FG table.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from .gpu_backend import TexturePool, upload
from .shaders import DFG_SIZE, MAX_PYRAMID_LEVELS, get_pass, pack_params


@dataclass
class ChainInputs:
    """Per-frame inputs, as textures at full resolution."""
    radiance_tx: object         # lit scene colour the reflections are fetched from
    depth_tx: object
    normal_tx: object
    roughness_tx: object
    combined_tx: object
    specular_color_tx: object
    specular_indirect_tx: object
    f0_tx: object               # specular reflectance at normal incidence, for FG
    motion_tx: object           # screen offset to the previous frame in pixels (Vector pass)
    view_matrix: np.ndarray
    projection_matrix: np.ndarray
    clip_start: float
    clip_end: float
    # Pixels rougher than this get cheap rays; ties at it are expensive with this probability.
    ray_budget: tuple = (1.0, 1.0)

    @property
    def size(self):
        return self.depth_tx.width, self.depth_tx.height

    @property
    def camera(self):
        return self.view_matrix, self.projection_matrix, self.clip_start, self.clip_end

    @classmethod
    def from_passes(cls, passes, settings):
        """Upload FramePasses; the lit scene (Combined) is also what reflections show."""
        combined_tx = upload(passes.combined)
        return cls(
            radiance_tx=combined_tx, depth_tx=upload(passes.depth), normal_tx=upload(passes.normal),
            roughness_tx=upload(passes.roughness), combined_tx=combined_tx,
            specular_color_tx=upload(passes.specular_color),
            specular_indirect_tx=upload(passes.specular_indirect), f0_tx=upload(passes.f0),
            motion_tx=upload(passes.motion),
            view_matrix=passes.view_matrix, projection_matrix=passes.projection_matrix,
            clip_start=passes.clip_start, clip_end=passes.clip_end,
            ray_budget=ray_budget(passes.roughness, passes.depth, passes.clip_end, settings))


def ray_budget(roughness, depth, clip_end, settings):
    """(threshold, tie fraction) that gives the smoothest `expensive_ray_budget` share of
    traced pixels expensive rays, even where large areas share one roughness."""
    traced = np.sort(roughness[(depth < clip_end) & (roughness <= settings.max_roughness)])
    if traced.size == 0 or settings.expensive_ray_budget >= 1.0:
        return 1.0, 1.0
    allowed = int(settings.expensive_ray_budget * traced.size)
    if allowed == 0:
        return -1.0, 0.0
    threshold = float(traced[allowed - 1])
    below = np.count_nonzero(traced < threshold)
    ties = np.count_nonzero(traced == threshold)
    return threshold, (allowed - below) / ties


@dataclass
class ChainState:
    """What the chain keeps between frames: textures by role, temporal history, the frame counter."""
    pool: TexturePool = field(default_factory=TexturePool)
    history: tuple = None                 # (filtered_tx, count_tx) of the last frame, or None
    previous_world_to_clip: np.ndarray = None
    frame_index: int = 0
    dfg_tx: object = None                 # the FG table, computed once

    def reset_history(self):
        """Forget the past (camera cut, jump in the frame range)."""
        self.history = None
        self.previous_world_to_clip = None


@dataclass
class ChainOutputs:
    ray_hit_tx: object        # traced rays: (hit uv, pdf, confidence)
    ray_dir_tx: object        # (view direction, hit distance)
    ray_stats_tx: object      # (ray class, iterations, highest Hi-Z level, 0)
    reflection_tx: object     # (premultiplied reflected radiance, confidence), after the temporal filter
    history_count_tx: object  # frames accumulated per pixel
    final_tx: object          # composited image
    iterations: int           # jittered iterations run this frame


def pyramid_levels(size):
    """Sizes of a 2x2 reduction pyramid down to 1x1 (ceil halving), at most MAX_PYRAMID_LEVELS."""
    levels = [tuple(size)]
    while max(levels[-1]) > 1 and len(levels) < MAX_PYRAMID_LEVELS:
        width, height = levels[-1]
        levels.append((math.ceil(width / 2), math.ceil(height / 2)))
    return levels


def atlas_layout(levels):
    """(atlas size, per-level rectangles): level 0 at the origin, the rest stacked to its right."""
    rects = [(0, 0, *levels[0])]
    y = 0
    for width, height in levels[1:]:
        rects.append((levels[0][0], y, width, height))
        y += height
    atlas_width = levels[0][0] + (levels[1][0] if len(levels) > 1 else 0)
    return (atlas_width, max(levels[0][1], y)), rects


def build_pyramid(source_tx, reduction, pool, role, level_count=None):
    """Reduce SOURCE level by level ('hiz_downsample': min, 'color_downsample': mean) and pack
    the levels into one atlas texture; returns (atlas, rectangles)."""
    levels = pyramid_levels((source_tx.width, source_tx.height))[:level_count]
    atlas_size, rects = atlas_layout(levels)
    channels = 1 if reduction == "hiz_downsample" else 4
    atlas = pool.get(f"{role}_atlas", atlas_size, channels)
    packer = get_pass("pyramid_pack")
    level_tx = source_tx
    for index, rect in enumerate(rects):
        if index > 0:
            next_tx = pool.get(f"{role}_level{index}", rect[2:], channels)
            get_pass(reduction).draw([next_tx], samplers=(("source_tx", level_tx),))
            level_tx = next_tx
        packer.draw([atlas], samplers=(("level_tx", level_tx),),
                    constants=(("level_offset", rect[:2]),), region=rect)
    return atlas, rects


def _lap(timer, stage, texture):
    if timer:
        timer.lap(stage, texture)


def run_chain(inputs, settings, state, timer=None):
    """Run the chain on one frame; returns ChainOutputs and updates STATE's history.

    With no history (a still, or the first frame after a cut) the temporal filter
    accumulates `accumulate_frames` jittered iterations of trace and resolve.
    """
    size = inputs.size
    scale = 2 if settings.half_resolution else 1
    trace_size = (math.ceil(size[0] / scale), math.ceil(size[1] / scale))
    pool = state.pool

    hiz_tx, hiz_rects = build_pyramid(inputs.depth_tx, "hiz_downsample", pool, "hiz") \
        if settings.use_hiz else (inputs.depth_tx, [(0, 0, *size)])
    _lap(timer, "hiz", hiz_tx)
    color_tx, color_rects = build_pyramid(inputs.radiance_tx, "color_downsample", pool, "color",
                                          None if settings.use_cone_filter else 1)
    _lap(timer, "color_pyramid", color_tx)

    view, projection = inputs.view_matrix, inputs.projection_matrix
    world_to_clip = np.asarray(projection, np.float64) @ np.asarray(view, np.float64)
    use_history = settings.use_temporal and state.history is not None
    iterations = 1 if use_history or not settings.use_temporal else settings.accumulate_frames
    if not use_history:
        state.reset_history()
    # An animation keeps an exponential window of 1 / (1 - weight) frames; a still
    # averages every one of its iterations.
    history_frames = max(1.0 / (1.0 - settings.temporal_weight), iterations)
    for iteration in range(iterations):
        has_history = state.history is not None
        history_mode = 0 if not has_history else (2 if iteration > 0 else 1)
        previous = state.previous_world_to_clip if has_history else world_to_clip
        params = pack_params(inputs.camera, previous, size, trace_size, state.frame_index,
                             inputs.ray_budget, hiz_rects, color_rects, history_mode, history_frames, settings)
        blocks = (("params", params),)
        if state.dfg_tx is None:
            state.dfg_tx = pool.get("dfg", (DFG_SIZE, DFG_SIZE))
            get_pass("dfg_table").draw([state.dfg_tx], uniform_blocks=blocks)
        ray_hit_tx = pool.get("ray_hit", trace_size)
        ray_dir_tx = pool.get("ray_dir", trace_size)
        ray_stats_tx = pool.get("ray_stats", trace_size)
        get_pass("trace").draw(
            [ray_hit_tx, ray_dir_tx, ray_stats_tx],
            samplers=(("depth_tx", inputs.depth_tx), ("normal_tx", inputs.normal_tx),
                      ("roughness_tx", inputs.roughness_tx), ("hiz_tx", hiz_tx)),
            uniform_blocks=blocks)
        _lap(timer, "trace", ray_hit_tx)

        reflection_tx = pool.get("reflection", size)
        reflection_hit_tx = pool.get("reflection_hit", size)
        get_pass("resolve").draw(
            [reflection_tx, reflection_hit_tx],
            samplers=(("ray_hit_tx", ray_hit_tx), ("ray_dir_tx", ray_dir_tx), ("depth_tx", inputs.depth_tx),
                      ("normal_tx", inputs.normal_tx), ("roughness_tx", inputs.roughness_tx),
                      ("color_tx", color_tx)),
            uniform_blocks=blocks)
        _lap(timer, "resolve", reflection_tx)

        if settings.use_temporal:
            # Ping-pong: write into the pair the last frame did not write.
            parity = state.frame_index % 2
            filtered_tx = pool.get(f"history{parity}", size)
            count_tx = pool.get(f"history_count{parity}", size)
            history_tx, history_count_tx = state.history or (reflection_tx, reflection_hit_tx)
            get_pass("temporal").draw(
                [filtered_tx, count_tx],
                samplers=(("reflection_tx", reflection_tx), ("reflection_hit_tx", reflection_hit_tx),
                          ("depth_tx", inputs.depth_tx), ("motion_tx", inputs.motion_tx),
                          ("history_tx", history_tx), ("history_count_tx", history_count_tx)),
                uniform_blocks=blocks)
            _lap(timer, "temporal", filtered_tx)
            state.history = (filtered_tx, count_tx)
            reflection_tx, history_count_tx = filtered_tx, count_tx
        else:
            history_count_tx = None
        state.previous_world_to_clip = world_to_clip
        state.frame_index += 1

    final_tx = pool.get("final", size)
    get_pass("composite").draw(
        [final_tx], samplers=(("combined_tx", inputs.combined_tx),
                              ("specular_color_tx", inputs.specular_color_tx),
                              ("specular_indirect_tx", inputs.specular_indirect_tx),
                              ("reflection_tx", reflection_tx), ("f0_tx", inputs.f0_tx),
                              ("dfg_tx", state.dfg_tx), ("depth_tx", inputs.depth_tx),
                              ("normal_tx", inputs.normal_tx), ("roughness_tx", inputs.roughness_tx)),
        uniform_blocks=blocks)
    _lap(timer, "composite", final_tx)
    return ChainOutputs(ray_hit_tx=ray_hit_tx, ray_dir_tx=ray_dir_tx, ray_stats_tx=ray_stats_tx,
                        reflection_tx=reflection_tx, history_count_tx=history_count_tx,
                        final_tx=final_tx, iterations=iterations)
