"""Render the passes SSR needs for the current frame and read them into RenderPasses.

One render, set up once (render_setup), writes a multilayer EXR to a private temporary
folder that is read back (exr_render). The scene, its view layer and its materials are
exactly as before on return, even when the render fails halfway.
"""
import os
import tempfile

import numpy as np

from ..core.gpu_backend import lap
from ..core.inputs import BACKGROUND_DEPTH, RenderPasses
from ..core.lamp_split import LampLights
from .exr_render import pass_layer, render_to_exr
from .lamp_renders import emitter_specular, lamp_specular, offscreen_lamps
from .material_aovs import F0_AOV, ROUGHNESS_AOV, add_material_aovs
from .overrides import TemporaryChanges
from .scene_captures import SceneCaptures
from .render_setup import apply_render_setup, rendered_view_layer
from .scene_io import camera_matrices, shows_a_surface


def render_passes(scene, setup, timer=None, captures=None):
    """Render SCENE's current frame as SETUP (render_setup.decide_render) says; returns RenderPasses.

    EEVEE's Specular Light holds lamp highlights and probe/world reflections together, so the
    highlights are split off as setup.lamp_split says (eevee_lamp_light). TIMER (a StageTimer)
    gets the engine's render as "render" and the split, the add-on's own cost, as "lamp_split":
    a second render (the analytic split is a pass of the chain). Where setup.planar_capture asks,
    the passes carry the planar capture of the main reflector, timed as "planar_capture", and
    where setup.cube_size asks, the depth cube map, timed as "cube_capture": from CAPTURES
    (scene_captures.SceneCaptures, which may hold them from the frame before)."""
    camera = scene.camera
    view_layer = rendered_view_layer(scene)
    with tempfile.TemporaryDirectory(prefix="ssr_passes_") as folder, TemporaryChanges() as changes:
        apply_render_setup(setup, scene, view_layer, changes)
        material_warnings = tuple(add_material_aovs(scene, view_layer, changes))
        layers = render_to_exr(scene, os.path.join(folder, "passes.exr"), changes)
        lap(timer, "render")
        view, projection = camera_matrices(scene, *setup.rendered_size)
        if setup.engine == "eevee":
            specular_light = pass_layer(layers, "Glossy Direct")
            lamp_light, lamps = eevee_lamp_light(setup.lamp_split, layers,
                                                 lambda shadows: lamp_specular(scene, folder, timer, shadows))
        else:
            # Cycles' Glossy Direct holds what one glossy bounce reaches from an emitter: lamps,
            # the world and emissive surfaces; Glossy Indirect what other surfaces reflect.
            # SSR replaces all but the lamps the camera cannot see (never on screen): a
            # render with those lamps hidden gives the rest of Glossy Direct.
            glossy_direct = pass_layer(layers, "Glossy Direct")
            glossy_indirect = pass_layer(layers, "Glossy Indirect")
            hidden = offscreen_lamps(scene) if setup.lamp_split.method == "render" else []
            emitters = emitter_specular(scene, folder, hidden, timer) if hidden else glossy_direct
            specular_light = glossy_direct + glossy_indirect
            lamp_light, lamps = np.maximum(glossy_direct - emitters, 0.0), None
        passes = passes_from_layers(layers, surface_layers(layers), specular_light, lamp_light, view, projection,
                                    (camera.data.clip_start, camera.data.clip_end), setup.engine, setup.samples,
                                    material_warnings, lamps)
        passes.crop = setup.crop
        if captures is None and (setup.planar_capture != "off" or setup.cube_size):
            captures = SceneCaptures()  # for this frame alone, rendered
        if captures is not None:
            passes.capture = captures.planar(scene, view_layer, setup, passes, folder)
            if passes.capture is not None:
                lap(timer, "planar_capture")
            passes.cube = captures.cube(scene, view_layer, setup, folder)
            if passes.cube is not None:
                lap(timer, "cube_capture")
    return passes


def eevee_lamp_light(split, layers, render_lamps):
    """(lamp_light, lamps) of RenderPasses for the lamp highlights in EEVEE's "Specular Light"
    (LAYERS, a frame's passes by name) as SPLIT (render_setup.LampSplit) says; RENDER_LAMPS(shadows)
    renders the specular light of the lamps alone."""
    if split.method == "off" or not split.has_lamps:
        return np.zeros_like(pass_layer(layers, "Glossy Direct")), None
    # The Shadow pass is each sample's shadowed share of all lamp light (every lamp,
    # diffuse and specular together): exact for one lamp, a lamp-weighted mean for more.
    if split.method == "analytic":
        return None, LampLights(split.lamps, pass_layer(layers, "Shadow")[..., 0])
    if split.method == "unshadowed":
        return render_lamps(False) * pass_layer(layers, "Shadow")[..., :1], None
    return render_lamps(True), None


def undo_coverage(value, coverage, fallback):
    """A shader AOV as the surface wrote it: the pixel filter averaged VALUE with the nothing
    around an edge, by the share COVERAGE the surface covers; FALLBACK where no surface did."""
    if value.ndim == 3:
        coverage = coverage[..., None]
    return np.ascontiguousarray(np.where(coverage > 1e-3, value / np.maximum(coverage, 1e-3), fallback),
                                dtype=np.float32)


def surface_layers(layers):
    """(depth, normal, roughness, coverage) of LAYERS (a render's passes by name): the
    world's depth set to BACKGROUND_DEPTH, roughness as the surfaces wrote it."""
    aov = pass_layer(layers, ROUGHNESS_AOV)
    coverage = aov[..., 1]
    roughness = np.clip(undo_coverage(aov[..., 0], coverage, fallback=1.0), 0.0, 1.0).astype(np.float32)
    normal = pass_layer(layers, "Normal")
    depth = pass_layer(layers, "Depth")[..., 0].copy()
    # The world has no normal; its depth is about clip_end in EEVEE (sometimes a hair
    # below it) and 1e10 in Cycles. Give it one unmistakable value.
    depth[~shows_a_surface(normal)] = BACKGROUND_DEPTH
    return depth, normal, roughness, coverage


def passes_from_layers(layers, surface, specular_light, lamp_light, view, projection, clip, engine, samples,
                       material_warnings=(), lamps=None):
    """RenderPasses from LAYERS ({pass name: image}, the names of a render's multilayer EXR:
    Combined, Depth, Normal, Glossy Color, the material AOVs (F0's may be left out: f0 None),
    Vector if any), their SURFACE (surface_layers), the specular light and its lamp highlights
    (or the LAMPS the chain splits off), the camera's matrices and CLIP (clip_start, clip_end)."""
    depth, normal, roughness, coverage = surface
    return RenderPasses(
        combined=pass_layer(layers, "Combined"),
        depth=depth,
        normal=normal,
        roughness=roughness,
        specular_color=pass_layer(layers, "Glossy Color"),
        f0=undo_coverage(pass_layer(layers, F0_AOV)[..., :3], coverage, fallback=0.0) if F0_AOV in layers
        else None,
        # Cycles has no Vector pass while motion blur is on: then objects count as still.
        motion=np.ascontiguousarray(layers["Vector"][..., :2]) if "Vector" in layers
        else np.zeros(depth.shape + (2,), np.float32),
        specular_light=specular_light,
        lamp_light=lamp_light,
        view_matrix=view, projection_matrix=projection,
        clip_start=clip[0], clip_end=clip[1], engine=engine, samples=samples,
        material_warnings=tuple(material_warnings), lamps=lamps)
