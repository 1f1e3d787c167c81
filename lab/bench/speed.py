"""Speed's yardstick, the full-screen copy pass timed on this GPU in the same run, and the chain's
milliseconds per stage at the deck's 1600x900 (make bench-chain, the slides' Performance)."""
import dataclasses
import statistics

import numpy as np

from ssr_addon.blender.gpu_context import ensure_backend
from ssr_addon.blender.render_passes import render_passes
from ssr_addon.blender.render_setup import decide_render
from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.chain import ChainState, run_chain
from ssr_addon.core.gpu_backend import StageTimer, empty_texture
from ssr_addon.core.gpu_passes import CHAIN_STAGES, COPY
from ssr_addon.core.inputs import ChainInputs
from .scenes import resolve_scene

COPY_PASS_REPEATS = 20
COPY_PASS_LARGE = (1600, 900)


def copy_pass_ms(size, repeats=COPY_PASS_REPEATS):
    """Median milliseconds of the full-screen copy pass (one RGBA32F texelFetch per pixel) at SIZE."""
    copy, target = _copy_pass(size)
    samples = []
    for repeat in range(repeats + 1):
        timer = StageTimer()
        timer.lap("idle", target)  # start with the GPU idle
        copy()
        timer.lap("copy", target)
        if repeat:  # the first draw warms up (allocation, shader compilation)
            samples.append(timer.milliseconds["copy"])
    return statistics.median(samples)


def queued_copy_pass_ms(size, count=COPY_PASS_REPEATS):
    """Milliseconds per copy pass at SIZE when COUNT copies are queued and waited for once: the
    GPU's throughput, without the wait for each pass that copy_pass_ms includes (about half a
    millisecond on a discrete GPU, far more than the copy itself)."""
    copy, target = _copy_pass(size)
    copy()  # warm-up
    timer = StageTimer()
    timer.lap("idle", target)
    for _ in range(count):
        copy()
    timer.lap("copies", target)
    return timer.milliseconds["copies"] / count


def _copy_pass(size):
    """(a call that draws one full-screen copy at SIZE, the texture it draws into)."""
    ensure_backend()
    source, target = empty_texture(size), empty_texture(size)
    return (lambda: COPY.draw([target], samplers=(("source_tx", source),))), target


def _size_label(size):
    return f"{size[0]}x{size[1]}"


def upscaled_passes(scene, size=COPY_PASS_LARGE, factor=5):
    """SCENE's EEVEE passes rendered at SIZE / FACTOR and repeated up to SIZE: real content at the
    pixel count being timed, without a minutes-long software render."""
    small = render_passes(scene, decide_render(scene, samples=4, resolution=(size[0] // factor, size[1] // factor)))

    def upscaled(value):
        if isinstance(value, np.ndarray) and value.shape[:2] == small.depth.shape:
            return value.repeat(factor, axis=0).repeat(factor, axis=1)
        return value
    ensure_backend()
    lamps = small.lamps and dataclasses.replace(small.lamps, shadow=upscaled(small.lamps.shadow))
    return dataclasses.replace(small, lamps=lamps, **{field.name: upscaled(getattr(small, field.name))
                                                     for field in dataclasses.fields(small) if field.name != "lamps"})


def bench_scene_passes(scene_name="mirror_floor"):
    """(the bench scene SCENE_NAME, its passes at COPY_PASS_LARGE: upscaled_passes)."""
    scene = load_scene(resolve_scene(scene_name))
    return scene, upscaled_passes(scene)


def chain_stage_ms(passes, settings, frames):
    """Median milliseconds per stage (CHAIN_STAGES) over FRAMES frames of a still shot of PASSES,
    after a first frame that compiles the shaders and fills the history; also returns the
    shot's ChainInputs and ChainState, to go on timing it (queued_frame_ms)."""
    inputs = ChainInputs.from_passes(passes, settings)
    state = ChainState()
    state.begin_frame(0)
    run_chain(inputs, settings, state)
    timings = {stage: [] for stage in CHAIN_STAGES}
    for frame in range(1, frames + 1):
        state.begin_frame(frame)
        timer = StageTimer()
        run_chain(inputs, settings, state, timer)
        for stage in CHAIN_STAGES:
            timings[stage].append(timer.milliseconds.get(stage, 0.0))
    return {stage: statistics.median(values) for stage, values in timings.items()}, inputs, state


def queued_frame_ms(inputs, settings, state, frames):
    """Milliseconds per frame of FRAMES more frames of STATE's shot, timed with one wait at the end."""
    first = state.sequence.frame + 1
    timer = StageTimer()
    for frame in range(first, first + frames):
        state.begin_frame(frame)
        outputs = run_chain(inputs, settings, state)
    timer.lap("frames", outputs["final"])
    return timer.milliseconds["frames"] / frames
