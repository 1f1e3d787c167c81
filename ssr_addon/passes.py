"""Render the passes SSR needs for the current frame and read them into numpy.

One render writes a multilayer EXR to a private temporary folder; OpenImageIO
reads it back (Blender 5 writes one EXR part per pass). Arrays are float32 in
image order (row 0 is the top row).
"""
import contextlib
import functools
import os
import tempfile
from dataclasses import dataclass

import bpy
import numpy as np
import OpenImageIO as oiio

from .analytic_lamps import AnalyticLampLight, require_modelled, scene_lamps
from .errors import SSRError
from .gpu_backend import download, ensure_backend, lap, upload
from .overrides import TemporaryChanges
from .material_aovs import F0_AOV, ROUGHNESS_AOV, add_material_aovs
from .scene_io import camera_matrices, require_camera, require_square_pixels

ENGINES = {"eevee": "BLENDER_EEVEE", "cycles": "CYCLES"}
BACKGROUND_DEPTH = 1e10  # depth of pixels that show the world (past any clip_end)
# EEVEE's ray tracing set-ups, (method, options): its own screen-space ray tracing, the peer a
# Blender user would pick instead, at its defaults and at the highest quality its options allow;
# and the render SSR composites over: reflections from light probes (SSR replaces them), with
# EEVEE's horizon scan, which darkens diffuse and rough light where nearby geometry blocks it.
# Without ray tracing that occlusion is missing: rolling_ball's back wall came out 56 % brighter
# than Cycles', and SSR's FLIP on glossy_corridor's reflective pixels was 2.3x higher.
EEVEE_RAYTRACING = {
    "default": ("SCREEN", {}),
    "high": ("SCREEN", {"resolution_scale": "1", "screen_trace_quality": 1.0, "trace_max_roughness": 1.0}),
    "light_probe": ("PROBE", {}),
}
SSR_BASE_RAYTRACING = "light_probe"  # the set-up of every render and capture SSR composites over
# Splits whose lamp light is unshadowed and takes its shadows from EEVEE's Shadow pass.
SHADOWED_SPLITS = ("unshadowed", "analytic")


def use_eevee_raytracing(scene, preset, changes):
    """Through CHANGES, render SCENE with the EEVEE_RAYTRACING set-up PRESET."""
    method, options = EEVEE_RAYTRACING[preset]
    changes.set(scene.eevee, "use_raytracing", True)
    changes.set(scene.eevee, "ray_tracing_method", method)
    for option, value in options.items():
        changes.set(scene.eevee.ray_tracing_options, option, value)


@dataclass
class FramePasses:
    combined: np.ndarray         # (H, W, 4) the engine's final image, scene linear
    depth: np.ndarray            # (H, W) distance along the view axis; BACKGROUND_DEPTH for the world
    normal: np.ndarray           # (H, W, 3) world-space shading normal
    roughness: np.ndarray        # (H, W) 1 where no specular BSDF was rendered
    specular_color: np.ndarray   # (H, W, 3) the engine's pre-integrated specular reflectance (its FG)
    f0: np.ndarray               # (H, W, 3) specular reflectance at normal incidence (shader AOV)
    motion: np.ndarray           # (H, W, 2) screen offset to the previous frame, pixels, y up (Vector pass)
    specular_light: np.ndarray   # (H, W, 3) all reflected light, before FG: EEVEE's Specular Light,
                                 # Cycles' Glossy Direct + Indirect
    lamp_light: object           # the part of it that stays: highlights of lamps the camera cannot see,
                                 # (H, W, 3), or an AnalyticLampLight the chain computes on the GPU
    view_matrix: np.ndarray      # (4, 4) world to view
    projection_matrix: np.ndarray  # (4, 4) view to clip
    clip_start: float
    clip_end: float
    engine: str
    samples: int                 # samples per pixel the engine rendered with
    material_warnings: tuple = ()  # materials whose roughness/F0 the AOVs could not read, and what was assumed

    @property
    def size(self):
        return self.depth.shape[1], self.depth.shape[0]

    @functools.cached_property
    def specular_direct(self):
        """(H, W, 3) lamp highlights, kept as they are (read back from the GPU where analytic)."""
        if isinstance(self.lamp_light, AnalyticLampLight):
            ensure_backend()
            direct_tx, _ = self.lamp_light.split(upload(self.depth), upload(self.normal), upload(self.roughness),
                                                 upload(self.specular_light))
            return download(direct_tx, 3)
        return self.lamp_light

    @functools.cached_property
    def specular_indirect(self):
        """(H, W, 3) reflected light SSR replaces, before FG: probes/world and, with the scene's
        ray tracing on, EEVEE's own traced reflections (EEVEE); world, emissive and other
        surfaces (Cycles). As lamp_split.glsl splits it on the GPU."""
        return np.maximum(self.specular_light - self.specular_direct, 0.0)


def undo_coverage(value, coverage, fallback):
    """A shader AOV as the surface wrote it: the pixel filter averaged VALUE with the nothing
    around an edge, by the share COVERAGE the surface covers; FALLBACK where no surface did."""
    if value.ndim == 3:
        coverage = coverage[..., None]
    return np.ascontiguousarray(np.where(coverage > 1e-3, value / np.maximum(coverage, 1e-3), fallback),
                                dtype=np.float32)


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


def lamp_split_method(engine, lamp_split, scene=None):
    """The split LAMP_SPLIT (a ChainSettings.lamp_split) stands for with ENGINE and SCENE.

    auto is analytic with EEVEE when analytic_lamps models every light of SCENE (without
    SCENE, as when settings are checked before any frame, that is assumed), unshadowed when
    it does not, and render with Cycles, which has no Shadow pass. The splits' costs and
    errors are measured in benchmarks/lamp_split.py. With SCENE, analytic is refused for
    lights it cannot model."""
    if lamp_split in SHADOWED_SPLITS and engine != "eevee":
        raise SSRError(f"lamp_split={lamp_split} needs EEVEE's Shadow pass: with Cycles use render, auto or off")
    if lamp_split == "auto":
        if engine != "eevee":
            return "render"
        return "unshadowed" if scene is not None and scene_lamps(scene)[1] else "analytic"
    if lamp_split == "analytic" and scene is not None:
        require_modelled(scene_lamps(scene)[1])
    return lamp_split


def render_passes(scene, engine="eevee", samples=None, resolution=None, eevee_raytracing=None,
                  lamp_split="auto", timer=None):
    """Render SCENE's current frame with ENGINE and return its FramePasses.

    SAMPLES and RESOLUTION default to the scene's own (render_samples, render_size).
    EEVEE renders with the scene's own ray tracing setting (off: probe/world
    reflections; on: its screen-space diffuse light and reflections too, which
    SSR replaces where its rays hit), or with ray tracing on as
    `eevee_raytracing` names a preset of EEVEE_RAYTRACING.
    LAMP_SPLIT (ChainSettings.lamp_split, through lamp_split_method) is how lamp
    highlights are split off the specular light:
    analytic: EEVEE's lamps computed from the scene's lights, times the Shadow pass;
    render: a second render, lamps only (EEVEE) or lamps hidden (Cycles), exact;
    unshadowed: a second render of EEVEE's lamps only without shadows, times the Shadow pass;
    off: no split (specular_direct is zero), as when nothing replaces the indirect specular.
    TIMER (a StageTimer) gets the engine's render as "render" and the split, the add-on's
    own cost, as "lamp_split": a second render, or reading the lights for the analytic
    split, whose pass the chain times.
    The scene, its view layer and its materials are exactly as before on return.
    """
    camera = require_camera(scene)
    if engine not in ENGINES:
        raise SSRError(f"unknown engine {engine!r}: expected one of {', '.join(ENGINES)}")
    require_square_pixels(scene)
    samples = render_samples(scene, engine, samples)
    lamp_split = lamp_split_method(engine, lamp_split, scene)
    view_layer = rendered_view_layer(scene)
    with tempfile.TemporaryDirectory(prefix="ssr_passes_") as folder, TemporaryChanges() as changes:
        _configure_render(scene, view_layer, engine, samples, resolution, changes, eevee_raytracing)
        if lamp_split in SHADOWED_SPLITS:
            changes.set(view_layer, "use_pass_shadow", True)
        material_warnings = tuple(add_material_aovs(scene, view_layer, changes))
        layers = _render_to_exr(scene, os.path.join(folder, "passes.exr"), changes)
        lap(timer, "render")
        width, height = scene.render.resolution_x, scene.render.resolution_y
        view, projection = camera_matrices(scene, width, height)
        if engine == "eevee":
            specular_light = _layer(layers, "Glossy Direct")
            lamp_light = eevee_lamp_light(scene, layers, lamp_split, view, projection,
                                          lambda shadows: _lamp_specular(scene, folder, timer, shadows))
            if isinstance(lamp_light, AnalyticLampLight):
                lap(timer, "lamp_split")  # reading the scene's lights; the chain adds its pass
        else:
            # Cycles' Glossy Direct holds what one glossy bounce reaches from an emitter: lamps,
            # the world and emissive surfaces; Glossy Indirect what other surfaces reflect.
            # SSR replaces all but the lamps the camera cannot see (never on screen): a
            # render with those lamps hidden gives the rest of Glossy Direct.
            glossy_direct = _layer(layers, "Glossy Direct")
            glossy_indirect = _layer(layers, "Glossy Indirect")
            lamps = _offscreen_lamps(scene) if lamp_split == "render" else []
            emitter_specular = _emitter_specular(scene, folder, lamps, timer) if lamps else glossy_direct
            specular_light = glossy_direct + glossy_indirect
            lamp_light = np.maximum(glossy_direct - emitter_specular, 0.0)
    return frame_passes(layers, surface_layers(layers), specular_light, lamp_light, view, projection,
                        (camera.data.clip_start, camera.data.clip_end), engine, samples, material_warnings)


def rendered_view_layer(scene):
    """The view layer SSR renders: the first one enabled for rendering."""
    view_layer = next((layer for layer in scene.view_layers if layer.use), None)
    if view_layer is None:
        raise SSRError(f"scene '{scene.name}' has no view layer enabled for rendering")
    return view_layer


def eevee_lamp_light(scene, layers, lamp_split, view, projection, render_lamps):
    """The lamp highlights in EEVEE's "Specular Light" (LAYERS, a frame's passes), which holds
    them and probe/world reflections together: FramePasses.lamp_light. LAMP_SPLIT: a
    lamp_split_method; VIEW and PROJECTION: the camera's matrices; RENDER_LAMPS(shadows)
    renders the specular light of the lamps alone."""
    if lamp_split == "off" or not has_lamps(scene):
        return np.zeros_like(_layer(layers, "Glossy Direct"))
    # The Shadow pass is each sample's shadowed share of all lamp light (every lamp,
    # diffuse and specular together): exact for one lamp, a lamp-weighted mean for more.
    if lamp_split == "analytic":
        return AnalyticLampLight(scene_lamps(scene)[0], _layer(layers, "Shadow")[..., 0], view, projection,
                                 BACKGROUND_DEPTH)
    if lamp_split == "unshadowed":
        return render_lamps(False) * _layer(layers, "Shadow")[..., :1]
    return render_lamps(True)


def surface_layers(layers):
    """(depth, normal, roughness, coverage) of LAYERS (a render's passes by name): the
    world's depth set to BACKGROUND_DEPTH, roughness as the surfaces wrote it."""
    aov = _layer(layers, ROUGHNESS_AOV)
    coverage = aov[..., 1]
    roughness = np.clip(undo_coverage(aov[..., 0], coverage, fallback=1.0), 0.0, 1.0).astype(np.float32)
    normal = _layer(layers, "Normal")
    depth = _layer(layers, "Depth")[..., 0].copy()
    # The world has no normal; its depth is about clip_end in EEVEE (sometimes a hair
    # below it) and 1e10 in Cycles. Give it one unmistakable value.
    depth[np.linalg.norm(normal, axis=-1) < 0.5] = BACKGROUND_DEPTH
    return depth, normal, roughness, coverage


def frame_passes(layers, surface, specular_light, lamp_light, view, projection, clip, engine, samples,
                 material_warnings=()):
    """FramePasses from LAYERS ({pass name: image}, the names of a render's multilayer EXR:
    Combined, Depth, Normal, Glossy Color, the material AOVs, Vector if any), their SURFACE
    (surface_layers), the specular light and its lamp highlights, the camera's matrices and
    CLIP (clip_start, clip_end)."""
    depth, normal, roughness, coverage = surface
    passes_shape = depth.shape
    return FramePasses(
        combined=_layer(layers, "Combined"),
        depth=depth,
        normal=normal,
        roughness=roughness,
        specular_color=_layer(layers, "Glossy Color"),
        f0=undo_coverage(_layer(layers, F0_AOV)[..., :3], coverage, fallback=0.0),
        # Cycles has no Vector pass while motion blur is on: then objects count as still.
        motion=np.ascontiguousarray(layers["Vector"][..., :2]) if "Vector" in layers
        else np.zeros(passes_shape + (2,), np.float32),
        specular_light=specular_light,
        lamp_light=lamp_light,
        view_matrix=view, projection_matrix=projection,
        clip_start=clip[0], clip_end=clip[1], engine=engine, samples=samples,
        material_warnings=tuple(material_warnings))


def _configure_render(scene, view_layer, engine, samples, resolution, changes, eevee_raytracing=None):
    render = scene.render
    changes.set(render, "engine", ENGINES[engine])
    width, height = render_size(scene, resolution)
    changes.set_all(render, resolution_x=width, resolution_y=height, resolution_percentage=100)
    changes.set(render, "use_compositing", False)
    changes.set(render, "use_sequencer", False)
    for layer in scene.view_layers:
        changes.set(layer, "use", layer == view_layer)
    for flag in ("use_pass_combined", "use_pass_z", "use_pass_normal", "use_pass_vector",
                 "use_pass_glossy_direct", "use_pass_glossy_color"):
        changes.set(view_layer, flag, True)
    if engine == "eevee":
        changes.set(scene.eevee, "taa_render_samples", samples)
        if eevee_raytracing is not None:
            use_eevee_raytracing(scene, eevee_raytracing, changes)
    else:
        changes.set(view_layer, "use_pass_glossy_indirect", True)
        changes.set(scene.cycles, "samples", samples)
        changes.set(scene.cycles, "device", "CPU")


def _render_to_exr(scene, path, changes):
    changes.set_all(scene.render.image_settings, media_type="MULTI_LAYER_IMAGE",
                    file_format="OPEN_EXR_MULTILAYER", color_depth="32", exr_codec="ZIP")
    changes.set_all(scene.render, filepath=path, use_file_extension=False)
    try:
        bpy.ops.render.render(write_still=True, scene=scene.name)
    except RuntimeError as error:
        raise SSRError(f"render of scene '{scene.name}' failed: {str(error).strip()}") from None
    if not os.path.isfile(path):
        raise SSRError(f"render of scene '{scene.name}' wrote no image (is the render cancelled or empty?)")
    return read_multilayer_exr(path)


def read_multilayer_exr(path):
    """{pass name: (H, W, C) float32} of a Blender multilayer EXR (one part per pass)."""
    source = oiio.ImageInput.open(path)
    if source is None:
        raise SSRError(f"cannot read {path}: {oiio.geterror()}")
    layers = {}
    try:
        subimage = 0
        while source.seek_subimage(subimage, 0):
            spec = source.spec()
            pixels = source.read_image(subimage, 0, 0, spec.nchannels, "float")
            if pixels is None:
                raise SSRError(f"cannot read part {subimage} of {path}: {source.geterror()}")
            name = spec.getattribute("name") or spec.channelnames[0].rpartition(".")[0]
            layers[name.split(".", 1)[-1]] = np.ascontiguousarray(pixels, dtype=np.float32)
            subimage += 1
    finally:
        source.close()
    return layers


def _layer(layers, name):
    if name not in layers:
        raise SSRError(f"the render has no '{name}' pass (found: {', '.join(sorted(layers))})")
    return layers[name]


def has_lamps(scene):
    return any(obj.type == "LIGHT" and not obj.hide_render and obj.data.specular_factor > 0
               for obj in scene.objects)


_shared_lamp_world = []  # the black world of the innermost lamp_world_for_run, made on first use


@contextlib.contextmanager
def lamp_world_for_run():
    """Within it, every lamp-only render uses one black world, removed on exit. A new world
    for every frame makes EEVEE rebuild its world lighting (about 0.9 s a frame in scenes
    with light probes); a run renders frame after frame, so it keeps one."""
    _shared_lamp_world.append(None)
    try:
        yield
    finally:
        world = _shared_lamp_world.pop()
        if world is not None:
            bpy.data.worlds.remove(world)


def black_world(changes):
    """The run's black world, or (outside a run) one that CHANGES removes again."""
    if _shared_lamp_world and _shared_lamp_world[-1] is not None:
        return _shared_lamp_world[-1]
    world = bpy.data.worlds.new("ssr_black_world")
    world.color = (0.0, 0.0, 0.0)
    for node in world.node_tree.nodes if world.node_tree else ():
        if node.type == "BACKGROUND":
            node.inputs["Strength"].default_value = 0.0
    if _shared_lamp_world:
        _shared_lamp_world[-1] = world
    else:
        changes.on_restore(lambda: bpy.data.worlds.remove(world))
    return world


def lamps_alone(scene, changes, shadows=True):
    """Through CHANGES, light SCENE by its lamps alone: the world black, light probes hidden
    and ray tracing off (it would reflect the lamp-lit scene); without SHADOWS, no shadows."""
    changes.set(scene, "world", black_world(changes))
    changes.set(scene.eevee, "use_raytracing", False)
    if not shadows:
        changes.set(scene.eevee, "use_shadows", False)
    for obj in scene.objects:
        if obj.type == "LIGHT_PROBE":
            changes.set_all(obj, hide_render=True, hide_viewport=True)


def _lamp_specular(scene, folder, timer, shadows=True):
    """EEVEE's specular light of the lamps alone. Without SHADOWS it costs a fraction of a
    render (at 160x90 on llvmpipe 2 s against 12 s: shadow maps are updated every sample)."""
    with TemporaryChanges() as lamp_only:
        lamps_alone(scene, lamp_only, shadows)
        layers = _render_to_exr(scene, os.path.join(folder, "lamp_specular.exr"), lamp_only)
    lap(timer, "lamp_split")
    return _layer(layers, "Glossy Direct")


def _offscreen_lamps(scene):
    """Lamps that render but that the camera never sees: their glossy light stays in the image."""
    return [obj for obj in scene.objects
            if obj.type == "LIGHT" and not obj.hide_render and not obj.visible_camera]


def _emitter_specular(scene, folder, lamps, timer):
    """Cycles' Glossy Direct with LAMPS hidden: the reflected world and emissive surfaces
    (and camera-visible lamps), what SSR can see on screen. Glossy Direct is written at the
    first bounce, so no further bounce is traced (the pass is the same, sample for sample)."""
    with TemporaryChanges() as emitters_only:
        for lamp in lamps:
            emitters_only.set(lamp, "hide_render", True)
        emitters_only.set(scene.cycles, "max_bounces", 0)
        layers = _render_to_exr(scene, os.path.join(folder, "emitter_specular.exr"), emitters_only)
    lap(timer, "lamp_split")
    return _layer(layers, "Glossy Direct")
