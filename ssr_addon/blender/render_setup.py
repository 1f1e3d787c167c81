"""How one frame's passes are rendered, decided once (decide_render) and applied once
(apply_render_setup): engine, size, samples, EEVEE's ray tracing and the lamp split.

Every render and capture SSR composites over uses EEVEE's ray tracing with reflections from
light probes (SSR replaces them) and its horizon scan, which darkens diffuse and rough light
where nearby geometry blocks it. Without ray tracing that occlusion is missing: rolling_ball's
back wall came out 56 % brighter than Cycles', and SSR's FLIP on glossy_corridor's reflective
pixels was 2.3x higher.
"""
import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import SSRError
from ..core.settings import fallback_levels
from .lights import require_modelled, scene_lamps
from .scene_io import camera_matrices, require_camera, require_square_pixels

ENGINES = {"eevee": "BLENDER_EEVEE", "cycles": "CYCLES"}
# EEVEE's ray tracing set-ups, (method, options): its own screen-space ray tracing, the peer a
# Blender user would pick instead, at its defaults and at the highest quality its options
# allow; and the one SSR composites over.
EEVEE_RAYTRACING = {
    "default": ("SCREEN", {}),
    "high": ("SCREEN", {"resolution_scale": "1", "screen_trace_quality": 1.0, "trace_max_roughness": 1.0}),
    "light_probe": ("PROBE", {}),
}
SSR_BASE_RAYTRACING = "light_probe"
# Splits whose lamp light is unshadowed and takes its shadows from EEVEE's Shadow pass.
SHADOWED_SPLITS = ("unshadowed", "analytic")


@dataclass(frozen=True)
class LampSplit:
    """How a frame's lamp highlights are split off (lamp_split_method) and what with."""
    method: str                # analytic, render, unshadowed or off
    has_lamps: bool            # any light reflects: without one there is nothing to split
    lamps: tuple = ()          # the lights the analytic split models (blender.lights.scene_lamps)

    @property
    def needs_shadow_pass(self):
        return self.method in SHADOWED_SPLITS


@dataclass(frozen=True)
class RenderSetup:
    """Everything a frame's render of its passes is decided by."""
    engine: str                # a key of ENGINES
    size: tuple                # (width, height)
    samples: int               # per pixel
    raytracing: str = None     # a key of EEVEE_RAYTRACING, or None: the scene's own setting
    lamp_split: object = None  # LampSplit
    planar_capture: str = "off"  # off, auto (where the frame shows its reflector reflecting) or on
    max_roughness: float = 1.0   # of the pixels SSR traces from (the auto capture's yardstick)
    guard_band: tuple = (0, 0)   # pixels rendered beyond the frame on each side, (x, y)
    cube_size: int = 0           # pixels along a side of each depth cube map face; 0: no cube map
    capture_engine: str = "eevee"  # what renders the captures (ChainSettings.capture_engine)

    @property
    def rendered_size(self):
        """(width, height) of the render: the frame and its guard band."""
        return self.size[0] + 2 * self.guard_band[0], self.size[1] + 2 * self.guard_band[1]

    @property
    def crop(self):
        """(x, y, width, height) of the frame in the render (image order), or None without a band."""
        return (*self.guard_band, *self.size) if any(self.guard_band) else None


def render_size(scene, resolution=None):
    """(width, height) a render will have: RESOLUTION, or the scene's own at its percentage."""
    if resolution is not None:
        return tuple(resolution)
    render = scene.render
    return (render.resolution_x * render.resolution_percentage // 100,
            render.resolution_y * render.resolution_percentage // 100)


def render_samples(scene, engine, samples=None):
    """Samples per pixel a render will use: SAMPLES, or the scene's own setting for ENGINE."""
    if samples is not None:
        return samples
    return scene.eevee.taa_render_samples if engine == "eevee" else scene.cycles.samples


def lamp_split_method(engine, lamp_split, unmodelled=None):
    """The split LAMP_SPLIT (a ChainSettings.lamp_split) stands for with ENGINE, where
    UNMODELLED names the scene's lights the analytic split cannot model.

    auto is analytic with EEVEE when it models every light (with UNMODELLED None, as when
    settings are checked before any frame, that is assumed), unshadowed when it does not, and
    render with Cycles, which has no Shadow pass. The splits' costs and errors are measured in
    lab/lamp_split.py. With UNMODELLED, analytic is refused for lights it cannot model."""
    if lamp_split in SHADOWED_SPLITS and engine != "eevee":
        raise SSRError(f"lamp_split={lamp_split} needs EEVEE's Shadow pass: with Cycles use render, auto or off")
    if lamp_split == "auto":
        if engine != "eevee":
            return "render"
        return "unshadowed" if unmodelled else "analytic"
    if lamp_split == "analytic" and unmodelled is not None:
        require_modelled(unmodelled)
    return lamp_split


def has_lamps(scene):
    return any(obj.type == "LIGHT" and not obj.hide_render and obj.data.specular_factor > 0
               for obj in scene.objects)


def decide_lamp_split(scene, engine, lamp_split):
    """The LampSplit of SCENE's lights for LAMP_SPLIT (ChainSettings.lamp_split) with ENGINE,
    the lights read once."""
    reads_lights = engine == "eevee" and lamp_split in ("auto", "analytic")
    if reads_lights:
        # Lights' matrix_world as the render will see them: a light just added or moved by a
        # script reads stale ones until the depsgraph is evaluated.
        rendered_view_layer(scene).update()
    lamps, unmodelled = scene_lamps(scene) if reads_lights else ((), None)
    method = lamp_split_method(engine, lamp_split, unmodelled)
    return LampSplit(method, has_lamps(scene), tuple(lamps) if method == "analytic" else ())


def guard_band_pixels(size, share):
    """(x, y) pixels of a guard band of SHARE of each side's length, even so that half-resolution
    quads fall alike in the band and in the frame."""
    return tuple(2 * math.ceil(share * length / 2) for length in size)


def widen_camera(scene, setup, changes):
    """Through CHANGES, widen SCENE's camera for SETUP's guard band: the same pixels, lens and
    shift, on a sensor (or orthographic scale) larger by the band, so the frame is the
    render's centre crop. A camera whose projection does not follow raises SSRError."""
    camera = scene.camera.data
    (width, height), (banded_width, banded_height) = setup.size, setup.rendered_size
    _, projection = camera_matrices(scene, width, height)
    if camera.type == "PANO":
        raise SSRError("the guard band needs a perspective or orthographic camera, not a panoramic one")
    # Horizontal fit keeps the projection's x scale in hand; shifts count in sensor widths then.
    vertical_fit = camera.sensor_fit == "VERTICAL" or (camera.sensor_fit == "AUTO" and height > width)
    shift_scale = (height / width if vertical_fit else 1.0) * width / banded_width
    widen = banded_width / width
    changes.set(camera, "sensor_fit", "HORIZONTAL")
    if camera.type == "ORTHO":
        changes.set(camera, "ortho_scale", 2.0 / projection[0, 0] * widen)
    else:
        changes.set(camera, "sensor_width", 2.0 * camera.lens / projection[0, 0] * widen)
    changes.set_all(camera, shift_x=camera.shift_x * shift_scale, shift_y=camera.shift_y * shift_scale)
    _, banded = camera_matrices(scene, banded_width, banded_height)
    expected = np.diag((width / banded_width, height / banded_height, 1.0, 1.0)) @ projection
    if not np.allclose(banded, expected, rtol=1e-4, atol=1e-5):
        raise SSRError(f"camera '{scene.camera.name}': cannot widen it for the guard band exactly")


def planar_capture_mode(fallback):
    """RenderSetup.planar_capture for a ChainSettings.fallback."""
    levels = fallback_levels(fallback)
    return "auto" if levels is None else ("on" if "planar" in levels else "off")


def decide_render(scene, engine="eevee", samples=None, resolution=None, raytracing=None, lamp_split="auto",
                  fallback="off", max_roughness=1.0, guard_band=0.0, cube_size=0, capture_engine="eevee"):
    """The RenderSetup of SCENE's current frame: SAMPLES and RESOLUTION default to the scene's
    own (render_samples, render_size); RAYTRACING names an EEVEE_RAYTRACING set-up (None: the
    scene's own setting); LAMP_SPLIT is decide_lamp_split's; FALLBACK (ChainSettings.fallback)
    and MAX_ROUGHNESS decide the planar capture; GUARD_BAND is the share of each side rendered
    beyond the frame (0: none); CUBE_SIZE the depth cube map's face size (0: none);
    CAPTURE_ENGINE what renders the captures. Bad input raises SSRError."""
    require_camera(scene)
    if engine not in ENGINES:
        raise SSRError(f"unknown engine {engine!r}: expected one of {', '.join(ENGINES)}")
    require_square_pixels(scene)
    size = render_size(scene, resolution)
    return RenderSetup(engine, size, render_samples(scene, engine, samples), raytracing,
                       decide_lamp_split(scene, engine, lamp_split), planar_capture_mode(fallback), max_roughness,
                       guard_band_pixels(size, guard_band), cube_size, capture_engine)


def rendered_view_layer(scene):
    """The view layer SSR renders: the first one enabled for rendering."""
    view_layer = next((layer for layer in scene.view_layers if layer.use), None)
    if view_layer is None:
        raise SSRError(f"scene '{scene.name}' has no view layer enabled for rendering")
    return view_layer


def use_eevee_raytracing(scene, preset, changes):
    """Through CHANGES, render SCENE with the EEVEE_RAYTRACING set-up PRESET."""
    method, options = EEVEE_RAYTRACING[preset]
    changes.set(scene.eevee, "use_raytracing", True)
    changes.set(scene.eevee, "ray_tracing_method", method)
    for option, value in options.items():
        changes.set(scene.eevee.ray_tracing_options, option, value)


def apply_render_setup(setup, scene, view_layer, changes):
    """Through CHANGES, set SCENE up to render SETUP's passes on VIEW_LAYER alone."""
    render = scene.render
    changes.set(render, "engine", ENGINES[setup.engine])
    changes.set_all(render, resolution_x=setup.rendered_size[0], resolution_y=setup.rendered_size[1],
                    resolution_percentage=100)
    if setup.crop is not None:
        widen_camera(scene, setup, changes)
    changes.set(render, "use_compositing", False)
    changes.set(render, "use_sequencer", False)
    for layer in scene.view_layers:
        changes.set(layer, "use", layer == view_layer)
    for flag in ("use_pass_combined", "use_pass_z", "use_pass_normal", "use_pass_vector",
                 "use_pass_glossy_direct", "use_pass_glossy_color"):
        changes.set(view_layer, flag, True)
    if setup.engine == "eevee":
        changes.set(scene.eevee, "taa_render_samples", setup.samples)
        if setup.raytracing is not None:
            use_eevee_raytracing(scene, setup.raytracing, changes)
    else:
        changes.set(view_layer, "use_pass_glossy_indirect", True)
        changes.set(scene.cycles, "samples", setup.samples)
        changes.set(scene.cycles, "device", "CPU")
    if setup.lamp_split.needs_shadow_pass:
        changes.set(view_layer, "use_pass_shadow", True)
