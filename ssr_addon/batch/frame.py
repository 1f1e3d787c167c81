"""One frame: its passes rendered as a RenderRequest asks, the chain run over them where the
method is SSR, its layers read back (FrameImages), and its three files written together.

Shared by the command line and the operators: everything here takes the scene and a
RenderRequest, never bpy.context.
"""
from dataclasses import dataclass

import numpy as np

from ..blender.colour_management import write_display_png
from ..blender.gpu_context import ensure_backend
from ..blender.reflected_rays import reaching_geometry
from ..blender.scene_captures import SceneCaptures
from ..blender.render_passes import render_passes
from ..blender.render_setup import RenderSetup, decide_render, planar_capture_mode
from ..core.chain import ChainState, run_chain
from ..core.errors import SSRError
from ..core.gpu_backend import StageTimer, download, lap
from ..core.inputs import BACKGROUND_DEPTH, ChainInputs, crop_image
from ..core.ray_outcomes import unresolved_shares
from ..core.settings import fallback_levels
from ..core.uniforms import RAY_OUTCOMES
from ..core.layers import exr_channels, read_layers
from .outputs import write_exr, write_rgba_exr, written_together
from .request import RENDER_RAYTRACING
from .run_report import frame_paths


@dataclass
class FrameImages:
    """What one frame rendered: its PASSES (RenderPasses), the FINAL image (H, W, 4), every
    layer of its passes EXR by name (core.layers) and STATS of the chain's work."""
    passes: object
    final: np.ndarray
    layers: dict
    stats: dict


class FrameFallbacks:
    """The fallback hierarchy's state over a run of frames (a still is a run of one) or of views
    drawn through a 3D View (add_view_captures): the scene captures
    (blender.scene_captures.SceneCaptures) and, under fallback=auto, whether the run has a guard
    band and a depth cube map.
    The run's first frame decides those from what its rays left unresolved towards geometry
    (a ray that leaves the frame for an open sky finds in the world what it would find in a
    capture), and is rendered again with them where it needs either.
    A run of frames renders its captures (VIEWPORT None): drawn between a frame's renders, they
    made those renders slower (blender.scene_captures), and in Blender's window the 3D View is
    the artist's. A run of views draws them through the VIEWPORT its views are drawn through."""

    def __init__(self, viewport=None):
        self.captures = SceneCaptures(viewport)
        self.guard_band = self.cube = None  # undecided until the first frame under auto

    def decide(self, unresolved):
        """Decide the levels from the first frame's shares of light left unresolved towards
        geometry (unresolved_toward_geometry); True where the frame needs rendering again."""
        self.guard_band = unresolved["left_frame"] >= AUTO_GUARD_BAND_SHARE
        self.cube = unresolved["left_frame"] + unresolved["behind"] >= AUTO_CUBE_SHARE
        return self.guard_band or self.cube

    def reconsider(self):
        """Decide the levels afresh at the next first frame or held view (a view held elsewhere
        may lose other rays)."""
        self.guard_band = self.cube = None

    def release(self):
        self.captures.release()


# Under fallback=auto a run gets a guard band when at least this share of its first frame's
# reflected light was left to the probes and world by rays that left the frame towards
# geometry, and a depth cube map when at least AUTO_CUBE_SHARE was, by rays that left the
# frame or passed behind what it shows (after the planar capture, where the frame has one).
AUTO_GUARD_BAND_SHARE = 0.02
AUTO_CUBE_SHARE = 0.05


def render_frame(scene, request, state=None, fallbacks=None):
    """Render the scene's current frame as REQUEST asks; returns (FrameImages, StageTimer).

    STATE (a ChainState) carries temporal history from the previous frame; the
    caller has begun the frame in it (state.begin_frame). Without one the frame
    is a still, accumulated over `accumulate_iterations` iterations. FALLBACKS
    (FrameFallbacks) holds the run's fallback state from frame to frame; without it
    the frame is a run of its own. Where fallback=auto finds that the first frame needs
    a guard band or a cube map (FrameFallbacks), it is rendered again with them.
    """
    own_fallbacks = fallbacks is None
    fallbacks = fallbacks or FrameFallbacks()
    try:
        images, timer = _render_frame(scene, request, state, fallbacks)
        if images.stats.pop("render_again", False):
            if state is not None:
                state.reset_history()
                state.begin_frame(scene.frame_current, scene.camera.name)
            images, timer = _render_frame(scene, request, state, fallbacks, timer)
        return images, timer
    finally:
        if own_fallbacks:
            fallbacks.release()


def _render_frame(scene, request, state, fallbacks, earlier=None):
    timer = StageTimer(wait_for_gpu=request.time_stages)
    if earlier is not None:  # the render this one replaces is what deciding the levels cost
        timer.milliseconds["fallback_choice"] = sum(earlier.milliseconds.values())
    settings = request.settings
    use_ssr = request.method == "ssr" and settings.use_ssr
    levels = fallback_levels(settings.fallback) if use_ssr else ()
    guard_band = "guard_band" in levels if levels is not None else bool(fallbacks.guard_band)
    cube = "cube" in levels if levels is not None else bool(fallbacks.cube)
    setup = decide_render(scene, request.engine, request.samples, request.resolution,
                          RENDER_RAYTRACING.get(request.method), lamp_split=settings.lamp_split if use_ssr else "off",
                          fallback=settings.fallback if use_ssr else "off", max_roughness=settings.max_roughness,
                          guard_band=settings.guard_band_size if guard_band else 0.0,
                          cube_size=settings.cube_size if cube else 0, capture_engine=settings.capture_engine)
    if setup.lamp_split.method == "analytic":
        timer.lap("lamp_split")  # reading the scene's lights; the chain adds its pass
    made_before = len(fallbacks.captures.made)
    passes = render_passes(scene, setup, timer, fallbacks.captures)
    captured = fallbacks.captures.made[made_before:]
    timer.lap("render")  # reading the passes back
    if not use_ssr:
        return FrameImages(passes, passes.combined, read_layers(passes), {}), timer
    ensure_backend()
    inputs = ChainInputs.from_passes(passes, settings, timer)
    if state is None:
        state = ChainState.still()
        state.begin_frame(scene.frame_current)
    outputs = run_chain(inputs, settings, state, timer)
    crop = passes.crop
    # The brightest light the frame's rays could read: its whole render (guard band included)
    # and the captures', per channel (an energy bound's yardstick).
    seen = [passes.combined] + [capture.radiance for capture in (passes.capture, passes.cube) if capture is not None]
    brightest_seen = np.max([image[..., :3].reshape(-1, 3).max(axis=0) for image in seen], axis=0)
    layers = {name: crop_image(image, crop) for name, image in read_layers(passes, outputs).items()}
    passes = passes.cropped()
    stats = {**chain_stats(outputs, passes, layers, settings), "captured": captured,
             "brightest_seen": [round(float(value), 6) for value in brightest_seen]}
    if levels is None and fallbacks.guard_band is None:
        stats["unresolved_toward_geometry"] = unresolved_toward_geometry(scene, passes, layers, settings)
        stats["render_again"] = fallbacks.decide(stats["unresolved_toward_geometry"])
    images = FrameImages(passes, crop_image(download(outputs["final"]), crop), layers, stats)
    timer.lap("readback")
    return images, timer


def add_view_captures(scene, view_layer, passes, settings, fallbacks, samples, timer=None):
    """Give PASSES, a view drawn through the 3D View of FALLBACKS (a FrameFallbacks: the live
    view, preview), the captures SETTINGS' fallback asks for, drawn through that view with
    Combined at SAMPLES: the main reflector's planar capture, and the depth cube map where the
    fallback lists it or auto decided it (decide_view_cube). The guard band is a render's alone.
    TIMER gets "planar_capture" and "cube_capture" as a frame's does."""
    levels = fallback_levels(settings.fallback) if settings.use_ssr else ()
    cube = "cube" in levels if levels is not None else bool(fallbacks.cube)
    height, width = passes.depth.shape
    setup = RenderSetup("eevee", (width, height), samples, planar_capture=planar_capture_mode(
        settings.fallback if settings.use_ssr else "off"), max_roughness=settings.max_roughness,
        cube_size=settings.cube_size if cube else 0)
    passes.capture = fallbacks.captures.planar(scene, view_layer, setup, passes, folder=None)
    if passes.capture is not None:
        lap(timer, "planar_capture")
    passes.cube = fallbacks.captures.cube(scene, view_layer, setup, folder=None)
    if passes.cube is not None:
        lap(timer, "cube_capture")


def keep_view_captures(passes, held):
    """PASSES of a moving view with the captures of HELD, the passes of the view it moved from
    (add_view_captures): each capture keeps its own camera, so rays are traced in it from any
    view; drawing them again would cost a moving update as many draws again."""
    passes.capture, passes.cube = held.capture, held.cube
    return passes


def decide_view_cube(scene, passes, outputs, settings, fallbacks):
    """Under fallback=auto, decide from a view's first image (OUTPUTS of the chain over PASSES,
    with its planar capture) whether the views get the depth cube map, as a run's first frame
    decides (FrameFallbacks.decide); True where the cube was undecided and is now wanted."""
    if not settings.use_ssr or fallback_levels(settings.fallback) is not None or fallbacks.cube is not None:
        return False
    layers = read_layers(passes, outputs)
    fallbacks.decide(unresolved_toward_geometry(scene, passes, layers, settings))
    return fallbacks.cube


def chain_stats(outputs, passes, layers, settings):
    """The chain's work in a frame: iterations, rays traced in the last one, the share of them
    that were expensive (Hi-Z), and the share of the reflected light it left to the probes and
    world, by why (core.ray_outcomes)."""
    ray_class = download(outputs["ray_stats"])[..., 0]  # one entry per traced ray
    traced = np.count_nonzero(ray_class > 0)
    unresolved = unresolved_shares(layers["SSR Resolved By"][..., 0], layers["SSR Confidence"][..., 0],
                                   passes.specular_color.mean(axis=-1), traced_pixels(passes, settings))
    return {"iterations": outputs.iterations, "traced_rays": traced,
            "expensive_ray_fraction": round(np.count_nonzero(ray_class == 2) / traced, 4) if traced else 0.0,
            "unresolved": unresolved}


def traced_pixels(passes, settings):
    """(H, W) the pixels SSR traces from: geometry no rougher than max_roughness."""
    return (passes.depth < BACKGROUND_DEPTH) & (passes.roughness <= settings.max_roughness)


def unresolved_toward_geometry(scene, passes, layers, settings):
    """unresolved_shares counting only the light whose rays left the frame or passed behind
    what it shows towards an object of SCENE (blender.reflected_rays)."""
    outcome, confidence = layers["SSR Resolved By"][..., 0], layers["SSR Confidence"][..., 0]
    traced = traced_pixels(passes, settings)
    candidates = traced & (confidence < 1.0) & np.isin(
        np.rint(outcome), [RAY_OUTCOMES["left_frame"], RAY_OUTCOMES["behind"]])
    shares = unresolved_shares(outcome, confidence, passes.specular_color.mean(axis=-1), traced,
                               reaching_geometry(scene, passes, candidates))
    return {reason: shares[reason] for reason in ("left_frame", "behind")}


def write_frame(out_dir, frame, images, scene, prefix="frame_"):
    """Write one frame's three files under temporary names, then rename them together; returns
    the PNG's path."""
    final = images.final
    if not np.isfinite(final).all():
        raise SSRError(f"frame {frame}: the result has NaN or Inf pixels; nothing written")
    final_exr, png, passes_exr = frame_paths(out_dir, prefix, frame)
    with written_together([passes_exr, png, final_exr]) as (passes_partial, png_partial, final_partial):
        write_exr(passes_partial, exr_channels(images.layers))
        write_display_png(png_partial, final, scene)
        write_rgba_exr(final_partial, final)
    return png
