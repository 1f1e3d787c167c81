"""What a render is asked for: the method, engine, size, frames and chain settings
(RenderRequest), and the command line's words for them, checked in one line each."""
import re
from dataclasses import dataclass, field

from ..blender.render_setup import ENGINES, SSR_BASE_RAYTRACING, lamp_split_method
from ..core.errors import SSRError
from ..core.settings import ChainSettings


# ssr: this project; none: the scene's own reflections (probes and the world, and EEVEE's
# screen tracing where the scene has ray tracing on); cycles: the path-traced reference;
# eevee-rt / eevee-rt-high: EEVEE's own screen-space ray tracing.
METHODS = ("ssr", "none", "cycles", "eevee-rt", "eevee-rt-high")
EEVEE_RAYTRACING_METHODS = {"eevee-rt": "default", "eevee-rt-high": "high"}  # methods that are EEVEE's own
# The EEVEE ray-tracing set-up (render_setup.EEVEE_RAYTRACING) each method renders with; "none" and
# the baselines render the scene's own.
RENDER_RAYTRACING = {**EEVEE_RAYTRACING_METHODS, "ssr": SSR_BASE_RAYTRACING}
# Frames rendered (not written) before the first frame a run writes, so its temporal history is
# as warm as an uninterrupted run's (the filter averages ~10). The frame sequence draws a
# frame's random numbers from its number alone, so they trace the rays an uninterrupted run did.
DEFAULT_WARMUP_FRAMES = 8


@dataclass
class RenderRequest:
    out_dir: str
    method: str = "ssr"
    engine: str = "eevee"
    resolution: tuple = None     # (width, height) or the scene's own
    frames: tuple = None         # (first, last) inclusive, or the scene's current frame
    samples: int = None          # EEVEE TAA samples / Cycles samples; engine default if None
    settings: ChainSettings = field(default_factory=ChainSettings)
    on_error: str = "stop"       # a frame that fails: "stop" the run or "skip" to the next frame
    overwrite: bool = False      # replace the run in out_dir instead of resuming it (run_report)
    warmup: int = None           # frames rendered, not written, before the first frame to write (None:
    #                              DEFAULT_WARMUP_FRAMES for a range; none for one frame, a still)
    file_prefix: str = "frame_"  # frame N is written as {file_prefix}{N:04d}.exr, .png and .passes.exr
    mode: str = None             # the operators' comparison mode, when one applies a baseline
    time_stages: bool = False    # wait for the GPU after each chain stage to time it apart (benchmarks);
    #                              otherwise the GPU's work shows in "readback", and the frame is quicker

    def __post_init__(self):
        if self.method not in METHODS:
            raise SSRError(f"unknown method {self.method!r}: expected one of {', '.join(METHODS)}")
        if self.engine not in ENGINES:
            raise SSRError(f"unknown engine {self.engine!r}: expected one of {', '.join(ENGINES)}")
        if self.method == "cycles":
            self.engine = "cycles"  # the reference is a Cycles path trace by definition
        if self.method in EEVEE_RAYTRACING_METHODS:
            self.engine = "eevee"
        if self.samples is not None and self.samples < 1:
            raise SSRError(f"--samples must be at least 1, got {self.samples}")
        lamp_split_method(self.engine, self.settings.lamp_split)  # one line now, not at the first frame
        if self.warmup is not None and self.warmup < 0:
            raise SSRError(f"--warmup must be 0 or more frames, got {self.warmup}")
        if self.on_error not in ("stop", "skip"):
            raise SSRError(f"--on-error {self.on_error!r}: expected stop or skip")


def parse_resolution(text):
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text or "")
    if not match or not all(4 <= int(v) <= 16384 for v in match.groups()):
        raise SSRError(f"--resolution {text!r}: expected WIDTHxHEIGHT with each side in 4..16384, e.g. 320x180")
    return int(match.group(1)), int(match.group(2))


def parse_frames(text):
    match = re.fullmatch(r"\s*(-?\d+)\s*(?:-\s*(-?\d+)\s*)?", text or "")
    if not match:
        raise SSRError(f"--frames {text!r}: expected a frame number N or a range A-B")
    first = int(match.group(1))
    last = int(match.group(2)) if match.group(2) is not None else first
    if last < first:
        raise SSRError(f"--frames {text!r}: the range is reversed (last frame before first)")
    return first, last


def frame_numbers(scene, frames):
    """The frames to render; a range must lie inside the scene's own frame range."""
    if frames is None:
        return [scene.frame_current]
    first, last = frames
    if first < scene.frame_start or last > scene.frame_end:
        raise SSRError(f"--frames {first}-{last} lies outside scene '{scene.name}' "
                       f"(frames {scene.frame_start}-{scene.frame_end})")
    return list(range(first, last + 1))
