"""The renders of lamps alone that the rendered lamp splits need (lamp_split=render or
unshadowed), and the black world they share over a run."""
import contextlib
import os

import bpy

from ..core.gpu_backend import lap
from .exr_render import pass_layer, render_to_exr
from .overrides import TemporaryChanges

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


def lamp_specular(scene, folder, timer, shadows=True):
    """EEVEE's specular light of the lamps alone. Without SHADOWS it costs a fraction of a
    render (at 160x90 on llvmpipe 2 s against 12 s: shadow maps are updated every sample)."""
    with TemporaryChanges() as lamp_only:
        lamps_alone(scene, lamp_only, shadows)
        layers = render_to_exr(scene, os.path.join(folder, "lamp_specular.exr"), lamp_only)
    lap(timer, "lamp_split")
    return pass_layer(layers, "Glossy Direct")


def offscreen_lamps(scene):
    """Lamps that render but that the camera never sees: their glossy light stays in the image."""
    return [obj for obj in scene.objects
            if obj.type == "LIGHT" and not obj.hide_render and not obj.visible_camera]


def emitter_specular(scene, folder, lamps, timer):
    """Cycles' Glossy Direct with LAMPS hidden: the reflected world and emissive surfaces
    (and camera-visible lamps), what SSR can see on screen. Glossy Direct is written at the
    first bounce, so no further bounce is traced (the pass is the same, sample for sample)."""
    with TemporaryChanges() as emitters_only:
        for lamp in lamps:
            emitters_only.set(lamp, "hide_render", True)
        emitters_only.set(scene.cycles, "max_bounces", 0)
        layers = render_to_exr(scene, os.path.join(folder, "emitter_specular.exr"), emitters_only)
    lap(timer, "lamp_split")
    return pass_layer(layers, "Glossy Direct")
