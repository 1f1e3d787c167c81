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

from .analytic_lamps import AnalyticLampLight
from .convergence import ConvergenceCheck
from .frame_sequence import FrameSequence
from .gpu_backend import TexturePool, lap, uniform_buffer, upload
from .gpu_params import MAX_PYRAMID_LEVELS, RAY_SAMPLING_CODES
from .shaders import DFG_SIZE, get_pass


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
    specular_direct_tx: object = None  # lamp highlights the chain split off (analytic), None if the passes had them

    @property
    def size(self):
        return self.depth_tx.width, self.depth_tx.height

    @classmethod
    def from_passes(cls, passes, settings, timer=None):
        """Upload FramePasses (TIMER: "upload"); the lit scene (Combined) is also what reflections
        show. Lamp highlights computed on the GPU are split off here ("lamp_split")."""
        combined_tx = upload(passes.combined)
        depth_tx, normal_tx, roughness_tx = upload(passes.depth), upload(passes.normal), upload(passes.roughness)
        analytic = isinstance(passes.lamp_light, AnalyticLampLight)
        specular_tx = upload(passes.specular_light if analytic else passes.specular_indirect)
        uploaded = dict(
            radiance_tx=combined_tx, depth_tx=depth_tx, normal_tx=normal_tx, roughness_tx=roughness_tx,
            combined_tx=combined_tx, specular_color_tx=upload(passes.specular_color),
            f0_tx=upload(passes.f0), motion_tx=upload(passes.motion),
            view_matrix=passes.view_matrix, projection_matrix=passes.projection_matrix,
            clip_start=passes.clip_start, clip_end=passes.clip_end,
            ray_budget=ray_budget(passes.roughness, passes.depth, passes.clip_end, settings))
        lap(timer, "upload")
        if not analytic:
            return cls(specular_indirect_tx=specular_tx, **uploaded)
        direct_tx, indirect_tx = passes.lamp_light.split(depth_tx, normal_tx, roughness_tx, specular_tx)
        lap(timer, "lamp_split", indirect_tx)
        return cls(specular_indirect_tx=indirect_tx, specular_direct_tx=direct_tx, **uploaded)


ROUGHNESS_BINS = 4096  # ray_budget's histogram: only the bin holding the threshold is sorted


def ray_budget(roughness, depth, clip_end, settings):
    """(threshold, tie fraction) that gives the smoothest `expensive_ray_budget` share of
    traced pixels expensive rays, and every pixel at most `sharp_roughness`, even where
    large areas share one roughness. Exact, without sorting every pixel (40 ms at
    1600x900): a histogram finds the bin the threshold lies in, and only that bin is sorted."""
    traced = roughness[(depth < clip_end) & (roughness <= settings.max_roughness)]
    if traced.size == 0 or settings.expensive_ray_budget >= 1.0:
        return 1.0, 1.0
    sharp = int(np.count_nonzero(traced <= settings.sharp_roughness))
    allowed = max(int(settings.expensive_ray_budget * traced.size), sharp)
    if allowed == 0:
        return -1.0, 0.0
    bins = np.clip((traced * ROUGHNESS_BINS).astype(np.int32), 0, ROUGHNESS_BINS - 1)
    cumulative = np.cumsum(np.bincount(bins, minlength=ROUGHNESS_BINS))
    threshold_bin = int(np.searchsorted(cumulative, allowed))  # the bin holding the allowed-th smoothest
    below_bin = int(cumulative[threshold_bin - 1]) if threshold_bin > 0 else 0
    in_bin = np.sort(traced[bins == threshold_bin])
    threshold = float(in_bin[allowed - below_bin - 1])
    below = below_bin + np.count_nonzero(in_bin < threshold)
    ties = np.count_nonzero(in_bin == threshold)
    return threshold, (allowed - below) / ties


@dataclass
class ChainState:
    """What the chain keeps between frames: textures by role, the frame sequence (sample
    indices and history slots), the last camera."""
    pool: TexturePool = field(default_factory=TexturePool)
    sequence: FrameSequence = field(default_factory=FrameSequence)
    previous_world_to_clip: np.ndarray = None
    previous_radiance_tx: object = None   # the last frame's lit scene: what its reflections showed
    convergence: ConvergenceCheck = field(default_factory=ConvergenceCheck)  # holds the last check's reflection
    dfg_tx: object = None                 # the FG table, computed once

    @classmethod
    def still(cls):
        """State for stills: each frame accumulates its own iterations, nothing carries over."""
        return cls(sequence=FrameSequence(still=True))

    def begin_frame(self, frame, camera=None):
        """Start FRAME (seen through CAMERA); the history carries over unless the sequence breaks."""
        if not self.sequence.start_frame(frame, camera):
            self._forget_last_frame()

    def reset_history(self):
        """Forget the past (a failed frame): the next frame starts afresh."""
        self.sequence.forget()
        self._forget_last_frame()

    def _forget_last_frame(self):
        self.previous_world_to_clip = None
        self.previous_radiance_tx = None
        self.convergence.forget()


@dataclass
class ChainOutputs:
    ray_hit_tx: object        # traced rays: (hit uv, pdf, confidence)
    ray_dir_tx: object        # (view direction, hit distance)
    ray_stats_tx: object      # (ray class, iterations, highest Hi-Z level, 0)
    resolved_tx: object       # the resolve's (premultiplied radiance, confidence), last iteration
    spatial_tx: object        # the same after the spatial filter (the resolve's own with the filter off)
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
    """(atlas size, per-level rectangles, {parity: column size}): level 0 at the origin, the
    odd levels stacked in a column to its right, the even ones in a column right of that.
    Each column is one copy of the texture its levels are drawn into (build_pyramid), where
    they lie at x = 0 and at the same y."""
    heights, column_y = {1: 0, 0: 0}, []
    for index, (_, height) in enumerate(levels[1:], 1):
        column_y.append(heights[index % 2])
        heights[index % 2] += height
    columns = {1: (levels[1][0] if len(levels) > 1 else 0, heights[1]),
               0: (levels[2][0] if len(levels) > 2 else 0, heights[0])}
    column_x = {1: levels[0][0], 0: levels[0][0] + columns[1][0]}
    rects = [(0, 0, *levels[0])] + [(column_x[index % 2], y, *size)
                                    for index, (y, size) in enumerate(zip(column_y, levels[1:]), 1)]
    return (column_x[0] + columns[0][0], max(levels[0][1], heights[1], heights[0])), rects, columns


def build_pyramid(source_tx, reduction, pool, role, level_count=None):
    """Reduce SOURCE level by level ('hiz_downsample': min, 'color_downsample': mean) and pack
    the levels into one atlas texture; returns (atlas, rectangles).

    Each level is one draw, into the column texture of its parity, reading the level before
    from the other one (a texture may not be read while drawn into); then three copies make
    the atlas: the source as level 0, and each column."""
    levels = pyramid_levels((source_tx.width, source_tx.height))[:level_count]
    atlas_size, rects, columns = atlas_layout(levels)
    channels = 1 if reduction == "hiz_downsample" else 4
    atlas = pool.get(f"{role}_atlas", atlas_size, channels)
    column_tx = {parity: pool.get(f"{role}_column{parity}", size, channels)
                 for parity, size in columns.items() if size[1] > 0}
    source, source_rect = source_tx, rects[0]
    for index, (_, y, width, height) in enumerate(rects[1:], 1):
        target, rect = column_tx[index % 2], (0, y, width, height)
        get_pass(reduction).draw([target], samplers=(("source_tx", source),),
                                 constants=(("source_offset", source_rect[:2]), ("source_size", source_rect[2:]),
                                            ("level_offset", rect[:2])), region=rect)
        source, source_rect = target, rect
    packer = get_pass("pyramid_pack")
    first_level = {1: 1, 0: 2}  # of each column: its x in the atlas
    copies = [(source_tx, rects[0])] + [(texture, (rects[first_level[parity]][0], 0, *columns[parity]))
                                        for parity, texture in column_tx.items()]
    for texture, rect in copies:
        packer.draw([atlas], samplers=(("level_tx", texture),), constants=(("level_offset", rect[:2]),), region=rect)
    return atlas, rects


@dataclass
class FrameContext:
    """What every iteration of one frame shares: its inputs, settings and pyramids."""
    inputs: ChainInputs
    settings: object             # ChainSettings
    state: ChainState
    timer: object                # StageTimer or None
    size: tuple                  # (width, height) of the frame
    trace_size: tuple            # of the ray textures (half resolution: half of it)
    hiz_tx: object
    hiz_rects: list              # each Hi-Z level's place in hiz_tx
    color_tx: object
    color_rects: list
    world_to_clip: np.ndarray

    @property
    def resolve_size(self):
        """Of the resolve's own textures: the traced size when half-resolution rays are resolved
        there (resolve_resolution=half), the frame's otherwise."""
        settings = self.settings
        return self.trace_size if settings.half_resolution and settings.resolve_resolution == "half" else self.size


def chain_params(frame, iteration, history_mode, previous_world_to_clip):
    """The uniform block of one iteration of FRAME, every field by name (gpu_params.PARAMS_FIELDS)."""
    inputs, settings, size, trace_size = frame.inputs, frame.settings, frame.size, frame.trace_size
    hiz_rects, color_rects = frame.hiz_rects, frame.color_rects
    view = np.asarray(inputs.view_matrix, np.float64)
    projection = np.asarray(inputs.projection_matrix, np.float64)
    history_frames = 1.0 / (1.0 - settings.temporal_weight)
    return uniform_buffer({
        "view_to_clip": projection, "clip_to_view": np.linalg.inv(projection),
        "world_to_view": view, "view_to_world": np.linalg.inv(view),
        "previous_world_to_clip": previous_world_to_clip,
        "viewport_size": size, "pixel_size": (1.0 / size[0], 1.0 / size[1]), "trace_size": trace_size,
        "trace_scale": 2 if settings.half_resolution else 1,
        "resolve_scale": 2 if frame.resolve_size != size else 1,
        "sample_index": iteration.sample_index, "quad_phase": iteration.quad_phase,
        "noise_seed": iteration.noise_seed,
        "clip_start": inputs.clip_start, "clip_end": inputs.clip_end,
        "expensive_roughness": inputs.ray_budget[0], "expensive_tie_fraction": inputs.ray_budget[1],
        "hiz_levels": len(hiz_rects) if settings.use_hiz else 0, "hiz_max_iterations": settings.hiz_max_iterations,
        "thickness": settings.thickness, "max_distance": settings.max_distance,
        "trace_stride": settings.trace_stride, "trace_steps": settings.trace_steps,
        "refine_steps": settings.refine_steps, "border_fade": settings.border_fade,
        "camera_facing_fade": settings.camera_facing_fade, "max_roughness": settings.max_roughness,
        "use_importance_sampling": settings.use_importance_sampling,
        "ray_sampling": RAY_SAMPLING_CODES[settings.ray_sampling], "resolve_samples": settings.resolve_samples,
        "use_cone_filter": settings.use_cone_filter, "color_levels": len(color_rects),
        "use_firefly_guard": settings.use_firefly_guard, "denoise_radius": settings.denoise_radius,
        "reproject_hit": settings.temporal_reprojection == "hit", "history_mode": history_mode,
        "history_frames": history_frames,
        "hiz_level": _level_rects(hiz_rects), "color_level": _level_rects(color_rects),
    })


def _level_rects(rects):
    packed = np.zeros((MAX_PYRAMID_LEVELS, 4), np.float32)
    packed[:len(rects)] = rects
    return packed


class FrameRun:
    """One frame of the chain, iterated on demand: the pyramids are built once, then each
    `iterate` adds trace iterations to the frame's running mean and `composite` draws
    the image they give so far. run_chain renders a frame with it; the live viewport
    adds an iteration or two per timer tick, so its picture refines while the view holds.
    The caller starts the frame first (state.begin_frame).
    """

    def __init__(self, inputs, settings, state, timer=None):
        size = inputs.size
        scale = 2 if settings.half_resolution else 1
        trace_size = (math.ceil(size[0] / scale), math.ceil(size[1] / scale))
        pool = state.pool
        hiz_tx, hiz_rects = build_pyramid(inputs.depth_tx, "hiz_downsample", pool, "hiz") \
            if settings.use_hiz else (inputs.depth_tx, [(0, 0, *size)])
        lap(timer, "hiz", hiz_tx)
        color_tx, color_rects = build_pyramid(inputs.radiance_tx, "color_downsample", pool, "color",
                                              None if settings.use_cone_filter else 1)
        lap(timer, "color_pyramid", color_tx)
        world_to_clip = np.asarray(inputs.projection_matrix, np.float64) @ np.asarray(inputs.view_matrix, np.float64)
        self.frame = FrameContext(inputs, settings, state, timer, size, trace_size, hiz_tx, hiz_rects,
                                  color_tx, color_rects, world_to_clip)
        if not state.sequence.has_history:  # the last frame's reflection is no yardstick for this one
            state.convergence.forget()
        self.iterations = 0
        self.outputs = self.blocks = None

    def iterate(self, count=1):
        for _ in range(count):
            self.outputs, self.blocks = _run_iteration(self.frame, first=self.iterations == 0)
            self.iterations += 1

    def next_batch(self):
        """Iterations to add before the next convergence check, 0 once the frame is done.

        First the sequence's first iterations (FrameSequence.iteration_count). Then,
        until the running mean moves less than noise_threshold between two checks,
        double the iterations (FrameSequence.doubling): the change from n to 2n
        iterations is about 2n's own error. A frame with history first compares with
        the last frame's reflection: in a still shot it has settled already. The
        measurement (convergence.ConvergenceCheck) is the "convergence" stage.
        """
        frame = self.frame
        settings, state, sequence = frame.settings, frame.state, frame.state.sequence
        if self.iterations == 0:
            return sequence.iteration_count(settings)
        if not sequence.doubling(settings):
            return 0
        change = state.convergence.change(self.outputs["reflection_tx"], state.pool)
        lap(frame.timer, "convergence")
        done = change is not None and change <= settings.noise_threshold
        return 0 if done else sequence.doubling(settings)

    def composite(self):
        """Composite the iterations so far; returns ChainOutputs."""
        frame = self.frame
        inputs, state = frame.inputs, frame.state
        final_tx = state.pool.get("final", frame.size)
        get_pass("composite").draw(
            [final_tx], samplers=(("combined_tx", inputs.combined_tx),
                                  ("specular_color_tx", inputs.specular_color_tx),
                                  ("specular_indirect_tx", inputs.specular_indirect_tx),
                                  ("reflection_tx", self.outputs["reflection_tx"]), ("f0_tx", inputs.f0_tx),
                                  ("dfg_tx", state.dfg_tx), ("depth_tx", inputs.depth_tx),
                                  ("normal_tx", inputs.normal_tx), ("roughness_tx", inputs.roughness_tx)),
            uniform_blocks=self.blocks)
        lap(frame.timer, "composite", final_tx)
        state.previous_radiance_tx = inputs.radiance_tx
        return ChainOutputs(**self.outputs, final_tx=final_tx, iterations=self.iterations)


def run_chain(inputs, settings, state, timer=None):
    """Run the chain on one frame; returns ChainOutputs and updates STATE's history.

    The caller starts the frame first (state.begin_frame). With no history (a
    still, or an animation's first frame after a cut) the frame runs the
    sequence's first iterations (FrameSequence.iteration_count) and the
    temporal filter averages them; with history, one iteration is blended in.
    Either then doubles until it settles (FrameRun.next_batch).
    """
    run = FrameRun(inputs, settings, state, timer)
    while added := run.next_batch():
        run.iterate(added)
    return run.composite()


def _run_iteration(frame, first):
    """One trace iteration of FRAME (a FrameContext): trace, resolve, spatial and temporal filters;
    returns their textures by ChainOutputs field and its uniform blocks. FIRST: the frame's first
    iteration (its history is the previous frame's)."""
    inputs, settings, state, timer = frame.inputs, frame.settings, frame.state, frame.timer
    size, trace_size, world_to_clip = frame.size, frame.trace_size, frame.world_to_clip
    pool = state.pool
    sequence = state.sequence
    iteration = sequence.next_iteration(keeps_history=settings.use_temporal)
    has_history = iteration.read_slot is not None
    history_mode = 0 if not has_history else (1 if first else 2)
    previous = state.previous_world_to_clip if has_history else world_to_clip
    # A frame's own iterations see one instant: only its first compares with the last frame.
    previous_radiance_tx = state.previous_radiance_tx if history_mode == 1 else inputs.radiance_tx
    params = chain_params(frame, iteration, history_mode, previous)
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
                  ("roughness_tx", inputs.roughness_tx), ("hiz_tx", frame.hiz_tx)),
        uniform_blocks=blocks)
    lap(timer, "trace", ray_hit_tx)

    # Without history nothing reads it (history_lib.glsl); any texture not drawn into will do.
    history_count_in_tx = pool.get(f"history_count{iteration.read_slot}", size) if has_history else inputs.depth_tx
    resolve_size = frame.resolve_size
    at_half = resolve_size != size  # resolve_resolution=half: resolved at the traced size, then scaled up
    suffix = "_half" if at_half else ""
    resolved_tx = pool.get(f"reflection{suffix}", resolve_size)
    reflection_hit_tx = pool.get(f"reflection_hit{suffix}", resolve_size)
    get_pass("resolve").draw(
        [resolved_tx, reflection_hit_tx],
        samplers=(("ray_hit_tx", ray_hit_tx), ("ray_dir_tx", ray_dir_tx), ("depth_tx", inputs.depth_tx),
                  ("normal_tx", inputs.normal_tx), ("roughness_tx", inputs.roughness_tx),
                  ("color_tx", frame.color_tx), ("history_count_tx", history_count_in_tx)),
        uniform_blocks=blocks)
    if at_half:
        half_tx, half_hit_tx = resolved_tx, reflection_hit_tx
        resolved_tx, reflection_hit_tx = pool.get("reflection", size), pool.get("reflection_hit", size)
        get_pass("resolve_upscale").draw([resolved_tx, reflection_hit_tx],
                                         samplers=(("reflection_tx", half_tx), ("reflection_hit_tx", half_hit_tx)),
                                         uniform_blocks=blocks)
    lap(timer, "resolve", resolved_tx)

    spatial_tx = resolved_tx
    if settings.use_spatial_filter:
        spatial_tx = pool.get("reflection_spatial", size)
        get_pass("denoise_spatial").draw(
            [spatial_tx],
            samplers=(("reflection_tx", resolved_tx), ("reflection_hit_tx", reflection_hit_tx),
                      ("depth_tx", inputs.depth_tx), ("normal_tx", inputs.normal_tx),
                      ("roughness_tx", inputs.roughness_tx), ("history_count_tx", history_count_in_tx)),
            uniform_blocks=blocks)
        lap(timer, "spatial", spatial_tx)

    reflection_tx, history_count_tx = spatial_tx, None
    if settings.use_temporal:
        filtered_tx = pool.get(f"history{iteration.write_slot}", size)
        count_tx = pool.get(f"history_count{iteration.write_slot}", size)
        history_tx = pool.get(f"history{iteration.read_slot}", size) if has_history else spatial_tx  # not read then
        get_pass("temporal").draw(
            [filtered_tx, count_tx],
            samplers=(("reflection_tx", spatial_tx), ("reflection_hit_tx", reflection_hit_tx),
                      ("depth_tx", inputs.depth_tx), ("motion_tx", inputs.motion_tx),
                      ("radiance_tx", inputs.radiance_tx), ("previous_radiance_tx", previous_radiance_tx),
                      ("history_tx", history_tx), ("history_count_tx", history_count_in_tx)),
            uniform_blocks=blocks)
        lap(timer, "temporal", filtered_tx)
        reflection_tx, history_count_tx = filtered_tx, count_tx
    state.previous_world_to_clip = world_to_clip
    return {"ray_hit_tx": ray_hit_tx, "ray_dir_tx": ray_dir_tx, "ray_stats_tx": ray_stats_tx,
            "resolved_tx": resolved_tx, "spatial_tx": spatial_tx, "reflection_tx": reflection_tx,
            "history_count_tx": history_count_tx}, blocks
