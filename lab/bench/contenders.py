"""The contenders (the peers, our presets, our stages off in turn) and rendering them taking turns."""
import fnmatch
from dataclasses import dataclass, field, fields, replace

from ssr_addon.batch.frame import FrameFallbacks, render_frame
from ssr_addon.batch.request import RenderRequest
from ssr_addon.blender.baselines import apply_baseline
from ssr_addon.blender.lamp_renders import lamp_world_for_run
from ssr_addon.blender.overrides import TemporaryChanges
from ssr_addon.core.chain import ChainState
from ssr_addon.core.errors import SSRError
from ssr_addon.core.settings import PRESETS, STAGE_TOGGLES, ChainSettings


@dataclass(frozen=True)
class Contender:
    name: str
    method: str
    settings: ChainSettings = field(default_factory=ChainSettings)
    baseline: str = None  # a blender.baselines set-up (an EEVEE probe) the scene is rendered with

    def overrides(self):
        """Settings that differ from the defaults, for the record."""
        defaults = ChainSettings()
        return {f.name: getattr(self.settings, f.name) for f in fields(ChainSettings)
                if getattr(self.settings, f.name) != getattr(defaults, f.name)}


def all_contenders():
    """Every contender: the peers a user would pick instead, our presets, our stages off in turn."""
    # EEVEE at its best set-up: its ray tracing with its own plane probe on the scene's main
    # reflector (traced before the screen), or with a sphere probe where `compare` puts one
    # (what its screen rays fall back to).
    contenders = [Contender("none", "none"), Contender("eevee-rt", "eevee-rt"),
                  Contender("eevee-rt-high", "eevee-rt-high"),
                  Contender("eevee-rt-planar", "eevee-rt", baseline="planar"),
                  Contender("eevee-rt-probe", "eevee-rt", baseline="cubemap")]
    # The presets, lamp splits and stages are the chain's own, measured over screen space alone
    # (fallback=off): the captures' cost would hide theirs. `ssr balanced` is the default, every
    # fallback level its frame needs included, and the fallback contenders below take it apart.
    screen_alone = replace(ChainSettings(), fallback="off")
    for name, overrides in PRESETS.items():
        settings = replace(ChainSettings(), **overrides) if name == "balanced" else replace(screen_alone, **overrides)
        contenders.append(Contender(f"ssr {name}", "ssr", settings))
    for lamp_split in ("render", "unshadowed"):  # auto (analytic with EEVEE) against the rendered splits
        contenders.append(Contender(f"ssr balanced lamp_split={lamp_split}", "ssr",
                                    replace(screen_alone, lamp_split=lamp_split)))
    for toggle in STAGE_TOGGLES:
        contenders.append(Contender(f"ssr {toggle}=off", "ssr", replace(screen_alone, **{toggle: False})))
    # The fallback hierarchy: off (screen space alone), and with Cycles-free captures each level alone.
    for fallback in ("off", "guard_band", "planar", "cube"):
        contenders.append(Contender(f"ssr balanced fallback={fallback}", "ssr",
                                    replace(ChainSettings(), fallback=fallback)))
    return contenders


def select_contenders(patterns):
    contenders = all_contenders()
    if not patterns:
        return contenders
    unmatched = [p for p in patterns if not any(fnmatch.fnmatchcase(c.name, p) for c in contenders)]
    if unmatched:
        raise SSRError(f"--contenders {' '.join(repr(p) for p in unmatched)}: matches none of "
                       f"{', '.join(c.name for c in contenders)}")
    return [c for c in contenders if any(fnmatch.fnmatchcase(c.name, p) for p in patterns)]


def run_contenders(scene, contenders, options):
    """Render every contender for options.frames frames, taking turns frame by frame.

    Taking turns spreads any change in the machine's load over all contenders
    alike. Each contender keeps its own ChainState and draws each frame's
    random numbers as run_render does, so its frames are those of a still
    animation, with temporal history, and its own fallback state (captures kept from
    frame to frame, levels decided on the first), as a run. After the first frame (which accumulates
    a still's iterations, and the process's first render is quicker than any
    later one), frames alternate: one timed stage by stage, a GPU wait after
    each chain stage, the next timed whole, as a render runs. Returns {name:
    (final image of the last frame, {stage: ms} of the frames timed stage by
    stage, {stage: ms} of the frames timed whole)}, each stage's time the
    fastest over its frames (other processes only ever add time).
    """
    states = {contender.name: ChainState() for contender in contenders}
    fallbacks = {contender.name: FrameFallbacks() for contender in contenders if contender.method == "ssr"}
    finals, laps = {}, {contender.name: [] for contender in contenders}
    try:
        with lamp_world_for_run():  # as a batch render keeps it
            for index, frame in enumerate(range(scene.frame_current, scene.frame_current + options.frames)):
                time_stages = index % 2 == 1
                for contender in contenders:
                    state = states[contender.name]
                    state.begin_frame(frame)
                    request = RenderRequest(out_dir=options.out_dir, method=contender.method,
                                            resolution=options.resolution, samples=options.eevee_samples,
                                            settings=contender.settings, time_stages=time_stages)
                    with TemporaryChanges() as changes:
                        if contender.baseline is not None:
                            apply_baseline(scene, contender.baseline, changes)
                        images, timer = render_frame(scene, request, state, fallbacks.get(contender.name))
                    finals[contender.name] = images.final[..., :3]
                    laps[contender.name].append((time_stages, timer.milliseconds))
    finally:
        for kept in fallbacks.values():
            kept.release()
    results = {}
    for name, frames in laps.items():
        timed = frames[1:] or frames
        staged = [stages for apart, stages in timed if apart] or [stages for _, stages in timed]
        whole = [stages for apart, stages in timed if not apart] or staged
        # What the shot's captures cost, shared by its frames: a capture kept from frame to
        # frame is paid once, so its time is the mean over all of them, the first included.
        shared = {stage: sum(stages.get(stage, 0.0) for _, stages in frames) / len(frames)
                  for stage in SHOT_STAGES if any(stage in stages for _, stages in frames)}
        results[name] = (finals[name], {**_fastest(staged), **shared}, {**_fastest(whole), **shared})
    return results


# Stages a frame pays only where it captures (or chooses the fallback levels, on the first).
SHOT_STAGES = ("fallback_choice", "planar_capture", "cube_capture")


def _fastest(frames):
    """{stage: its fewest milliseconds over FRAMES ({stage: ms} each)}, SHOT_STAGES aside."""
    stages = [stage for stage in frames[0] if stage not in SHOT_STAGES]
    return {stage: min(frame.get(stage, 0.0) for frame in frames) for stage in stages}
