"""The SSR chain: a plain function from textures and settings to textures.

No bpy here: callers (CLI, operators, tests) hand in ChainInputs, keep a ChainState between
frames (temporal history, reused textures) and get ChainOutputs back. Stage timings go into
a StageTimer.

The passes are declared in gpu_passes and run in its order, the order of the slides: the lamp
split, Hi-Z pyramid, colour pyramid, then each iteration ray generation and tracing
(cheap/expensive classes, GGX + Halton, half resolution), resolve with neighbour reuse and cone
filtering, spatial and temporal filters, and last the composite with the FG table. A pass's
samplers read the frame's resources by name and its outputs write them (FrameRun.run).
"""
import math
from dataclasses import dataclass, field

import numpy as np

from . import gpu_passes
from .convergence import ConvergenceCheck
from .frame_sequence import FrameSequence
from .gpu_backend import TexturePool, lap, uniform_buffer
from .inputs import BACKGROUND_DEPTH
from .lamp_split import lamp_block
from .pyramids import build_pyramid
from .uniforms import CAPTURE_LEVELS, HISTORY_MODES, MAX_PYRAMID_LEVELS, RAY_SAMPLING_CODES


@dataclass
class ChainState:
    """What the chain keeps between frames: textures by role, the frame sequence (sample
    indices and history slots), the last camera."""
    pool: TexturePool = field(default_factory=TexturePool)
    sequence: FrameSequence = field(default_factory=FrameSequence)
    previous_world_to_clip: np.ndarray = None
    previous_radiance_tx: object = None   # the last frame's lit scene: what its reflections showed
    previous_captures: tuple = None       # the last frame's (planar, cube) captures: kept, or captured afresh
    convergence: ConvergenceCheck = field(default_factory=ConvergenceCheck)  # holds the last check's reflection
    # Only the camera moves between frames (NavigatedViews): the light at a hit is what it was, and
    # a change of it is the captures' noise (one sample now, many before), never a stale history.
    # A frame's first iteration then runs HISTORY_MODE_VIEW (temporal.glsl).
    scene_holds_still: bool = False

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
        self.previous_captures = None
        self.convergence.forget()


@dataclass
class ChainOutputs:
    """The textures the chain's passes wrote in a frame, by resource name (the outputs of
    gpu_passes: ray_hit, resolved, spatial, reflection, history_record, final... and, where it
    ran, the lamp split's), and how many jittered iterations it ran."""
    textures: dict
    iterations: int

    def __getitem__(self, resource):
        return self.textures[resource]

    def get(self, resource):
        return self.textures.get(resource)


@dataclass
class FrameContext:
    """What every pass of one frame shares: its inputs, settings, sizes and pyramids."""
    inputs: object               # ChainInputs
    settings: object             # ChainSettings
    state: ChainState
    timer: object                # StageTimer or None
    size: tuple                  # (width, height) of the frame
    trace_size: tuple            # of the ray textures (half resolution: half of it)
    world_to_clip: np.ndarray
    hiz_rects: list = None       # each Hi-Z level's place in the hiz atlas
    color_rects: list = None
    capture_color_rects: list = ()  # of the planar capture's colour pyramid
    cube_color_rects: list = ()     # of the cube's
    captures_changed: bool = False  # the captures are not those of the frame the history is from

    @property
    def resolve_size(self):
        """Of the resolve's own textures: the traced size when half-resolution rays are resolved
        there (resolve_resolution=half), the frame's otherwise."""
        settings = self.settings
        return self.trace_size if settings.half_resolution and settings.resolve_resolution == "half" else self.size

    def output_size(self, output):
        """The size of a gpu_passes.Output in this frame."""
        sizes = {"frame": self.size, "trace": self.trace_size, "resolve": self.resolve_size}
        return sizes[output.size] if isinstance(output.size, str) else tuple(output.size)


def frame_context(inputs, settings, state, timer=None):
    size = inputs.size
    scale = 2 if settings.half_resolution else 1
    trace_size = (math.ceil(size[0] / scale), math.ceil(size[1] / scale))
    world_to_clip = np.asarray(inputs.projection_matrix, np.float64) @ np.asarray(inputs.view_matrix, np.float64)
    return FrameContext(inputs, settings, state, timer, size, trace_size, world_to_clip)


def chain_params(frame, iteration, history_mode, previous_world_to_clip):
    """The uniform block of one iteration of FRAME, every field by name (uniforms.PARAMS_FIELDS)."""
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
        "frame_rect": inputs.frame_rect or (0, 0, *size),
        "trace_scale": 2 if settings.half_resolution else 1,
        "resolve_scale": 2 if frame.resolve_size != size else 1,
        "sample_index": iteration.sample_index, "quad_phase": iteration.quad_phase,
        "noise_seed": iteration.noise_seed,
        "clip_start": inputs.clip_start, "clip_end": inputs.clip_end,
        "expensive_roughness": inputs.ray_budget[0], "expensive_tie_fraction": inputs.ray_budget[1],
        "sharp_roughness": settings.sharp_roughness if gpu_passes.TRACE_SHARP.runs(frame) else -1.0,
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
        **_capture_params(inputs.capture, view, frame.capture_color_rects),
        **_cube_params(inputs.cube, frame.cube_color_rects, settings),
        "capture_levels": (CAPTURE_LEVELS["planar"] if inputs.capture is not None else 0)
                          | (CAPTURE_LEVELS["cube"] if inputs.cube is not None else 0),
        "captures_changed": frame.captures_changed, "probe_reflection": inputs.probe_reflection,
        "fg_from_specular_color": inputs.fg_from_specular_color,
        "capture_light_stands": inputs.probe_reflection and inputs.capture is not None and inputs.capture.path_traced,
    })


def _capture_params(capture, view_matrix, color_rects):
    if capture is None:
        return {"capture_from_this_view": 0, "capture_world_to_view": np.eye(4), "capture_view_to_clip": np.eye(4),
                "capture_plane": (0, 0, 0, 0), "capture_size": (1, 1), "capture_color_levels": 0,
                "capture_color_level": _level_rects(())}
    return {"capture_from_this_view": capture.drawn_for(view_matrix), "capture_world_to_view": capture.view_matrix,
            "capture_view_to_clip": capture.projection_matrix, "capture_plane": capture.plane,
            "capture_size": capture.depth.shape[::-1], "capture_color_levels": len(color_rects),
            "capture_color_level": _level_rects(color_rects)}


def _cube_params(cube, color_rects, settings):
    if cube is None:
        return {"cube_world_to_face": np.zeros((6, 4, 4)), "cube_centre": (0, 0, 0, 1), "cube_color_levels": 0,
                "cube_steps": 0, "cube_reach": 0.0, "cube_color_level": _level_rects(())}
    return {"cube_world_to_face": cube.face_views, "cube_centre": (*cube.centre, cube.side),
            "cube_color_levels": len(color_rects), "cube_steps": settings.cube_steps, "cube_reach": cube.reach,
            "cube_color_level": _level_rects(color_rects)}


def _level_rects(rects):
    packed = np.zeros((MAX_PYRAMID_LEVELS, 4), np.float32)
    if rects:
        packed[:len(rects)] = rects
    return packed


class FrameRun:
    """One frame of the chain, iterated on demand: the frame's passes and pyramids run once,
    then each `iterate` adds trace iterations to the frame's running mean and `composite` draws
    the image they give so far. run_chain renders a frame with it; the live viewport adds an
    iteration or two per timer tick, so its picture refines while the view holds.
    The caller starts the frame first (state.begin_frame).
    """

    def __init__(self, inputs, settings, state, timer=None):
        self.frame = frame = frame_context(inputs, settings, state, timer)
        self.resources = dict(inputs.textures)
        self.produced = {}  # the resources this frame's passes wrote: ChainOutputs
        self.resources["dfg"] = gpu_passes.dfg_table()  # read by the lamp split and the composite
        frame_blocks = (("lamp_block", lamp_block(inputs.lamps, frame.size, inputs.view_matrix,
                                                  inputs.projection_matrix, BACKGROUND_DEPTH)),) \
            if inputs.lamps is not None else ()
        for gpu_pass in gpu_passes.FRAME_PASSES:
            self.run(gpu_pass, frame_blocks)
        pool = state.pool
        hiz_tx, frame.hiz_rects = build_pyramid(self.resources["depth"], gpu_passes.HIZ_DOWNSAMPLE,
                                                gpu_passes.PYRAMID_PACK, pool) \
            if settings.use_hiz else (self.resources["depth"], [(0, 0, *frame.size)])
        lap(timer, gpu_passes.HIZ_DOWNSAMPLE.stage, hiz_tx)
        color_tx, frame.color_rects = build_pyramid(self.resources["radiance"], gpu_passes.COLOR_DOWNSAMPLE,
                                                    gpu_passes.PYRAMID_PACK, pool,
                                                    None if settings.use_cone_filter else 1)
        lap(timer, gpu_passes.COLOR_DOWNSAMPLE.stage, color_tx)
        self.resources.update(hiz=hiz_tx, color=color_tx)
        captures = (inputs.capture, inputs.cube)
        previous = state.previous_captures or (None, None)
        frame.captures_changed = any(capture is not None and capture is not before
                                     for capture, before in zip(captures, previous))
        state.previous_captures = captures
        if inputs.capture is not None:
            self.resources["capture_color"], frame.capture_color_rects = build_pyramid(
                self.resources["capture_radiance"], gpu_passes.COLOR_DOWNSAMPLE, gpu_passes.PYRAMID_PACK, pool,
                None if settings.use_cone_filter else 1, name="capture_color")
            lap(timer, gpu_passes.PLANAR_TRACE.stage, self.resources["capture_color"])
        if inputs.cube is not None:
            # Coarse levels blur across the faces' seams: a cone that wide is the lobe of a rough
            # surface, which barely shows them.
            self.resources["cube_color"], frame.cube_color_rects = build_pyramid(
                self.resources["cube_radiance"], gpu_passes.COLOR_DOWNSAMPLE, gpu_passes.PYRAMID_PACK, pool,
                None if settings.use_cone_filter else 1, name="cube_color")
            lap(timer, gpu_passes.CUBE_TRACE.stage, self.resources["cube_color"])
        if not state.sequence.has_history:  # the last frame's reflection is no yardstick for this one
            state.convergence.forget()
        self.iterations = 0
        self.blocks = None

    @property
    def settings(self):
        return self.frame.settings

    def run(self, gpu_pass, uniform_blocks=(), write_slot=None):
        """Run GPU_PASS where it runs in this frame: bind its samplers to the resources they name,
        draw into textures kept for its outputs, make those the resources; where it does not
        run, the resources it names stand in for its outputs. Laps its stage."""
        frame = self.frame
        if not gpu_pass.runs(frame):
            for resource, stand_in in gpu_pass.skipped:
                self.resources[resource] = self.resources[stand_in]
                self.produced[resource] = self.produced.get(stand_in)
            for resource, placeholder in gpu_pass.placeholders:
                self.resources[resource] = self.resources[placeholder]
                self.produced.pop(resource, None)
            return
        samplers = [(sampler, self.resources[sampler[:-len("_tx")]]) for sampler in gpu_pass.samplers]
        pool = frame.state.pool
        targets = [pool.get(f"{gpu_pass.name}.{output.name}{write_slot if output.history else ''}",
                            frame.output_size(output), output.channels) for output in gpu_pass.outputs]
        gpu_pass.draw(targets, samplers=samplers, uniform_blocks=uniform_blocks)
        for output, target in zip(gpu_pass.outputs, targets):
            self.resources[output.resource] = self.produced[output.resource] = target
        if gpu_pass.stage:
            lap(frame.timer, gpu_pass.stage, targets[0])

    def iterate(self, count=1):
        for _ in range(count):
            self._iterate_once(first=self.iterations == 0)
            self.iterations += 1

    def _iterate_once(self, first):
        """One trace iteration: the iteration passes over the frame's resources. FIRST: the
        frame's first iteration (its history is the previous frame's)."""
        frame, state, resources = self.frame, self.frame.state, self.resources
        iteration = state.sequence.next_iteration(keeps_history=frame.settings.use_temporal)
        has_history = iteration.read_slot is not None
        mode = "none" if not has_history else "still" if not first else "view" if state.scene_holds_still \
            else "animation"
        previous = state.previous_world_to_clip if has_history else frame.world_to_clip
        # A frame's own iterations see one instant: only its first compares with the last frame.
        light_may_change = mode == "animation"
        resources["previous_radiance"] = state.previous_radiance_tx if light_may_change else resources["radiance"]
        for output in gpu_passes.TEMPORAL.outputs:  # the history the iteration reads
            # Without history nothing reads it (history_lib.glsl); any texture not drawn into will do.
            resources[output.history[:-len("_tx")]] = state.pool.get(
                f"{gpu_passes.TEMPORAL.name}.{output.name}{iteration.read_slot}", frame.size) \
                if has_history else resources["depth"]
        self.blocks = (("params", chain_params(frame, iteration, HISTORY_MODES[mode], previous)),)
        for gpu_pass in gpu_passes.ITERATION_PASSES:
            self.run(gpu_pass, self.blocks, write_slot=iteration.write_slot)
        state.previous_world_to_clip = frame.world_to_clip

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
        change = state.convergence.change(self.resources["reflection"], state.pool)
        lap(frame.timer, gpu_passes.CONVERGENCE_TILES.stage)
        done = change is not None and change <= settings.noise_threshold
        return 0 if done else sequence.doubling(settings)

    def composite(self):
        """Composite the iterations so far; returns ChainOutputs."""
        self.run(gpu_passes.COMPOSITE, self.blocks)
        self.frame.state.previous_radiance_tx = self.resources["radiance"]
        return ChainOutputs(dict(self.produced), self.iterations)


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
