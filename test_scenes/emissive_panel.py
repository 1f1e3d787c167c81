"""A glossy metal floor under a bright emissive panel, a bright coloured world, a lamp
and a diffuse cube: the Cycles composite case.

What the floor reflects lands in different Cycles passes: the panel and the world
(emitters, one bounce) in Glossy Direct, the cube (lit by them) in Glossy Indirect,
the lamp (not visible to the camera) in Glossy Direct too. SSR sees the panel and
the cube on screen, never the lamp, and misses where the floor reflects the sky.
"""
from _common import add_camera, add_mesh, principled, set_render, set_world

import bpy

PANEL_CENTER = (-0.6, 3.0, 1.0)   # an upright plane facing the camera, bottom edge on the floor
PANEL_SIZE = (1.2, 1.0)           # half width (x), half height (z)
PANEL_EMISSION = (1.0, 0.55, 0.2)
PANEL_STRENGTH = 6.0
FLOOR_ROUGHNESS = 0.08
# In front of the cube: where the floor mirrors the lamp it mirrors the cube's face behind
# it, so SSR replaces that reflection and the lamp's highlight must stay on top of it.
LAMP_LOCATION = (2.0, 0.9, 0.5)


def build(scene):
    set_render(scene, 160, 90)
    set_world(scene, (0.45, 0.6, 1.0), strength=2.5)
    floor = principled("GlossyMetal", base_color=(0.9, 0.9, 0.9), roughness=FLOOR_ROUGHNESS, metallic=1.0)
    add_mesh(scene, "plane", "Floor", (0, 0, 0), 10.0, floor)
    panel_material = principled("Panel", base_color=(0.0, 0.0, 0.0), roughness=1.0,
                                emission=PANEL_EMISSION, emission_strength=PANEL_STRENGTH)
    panel_material.node_tree.nodes["Principled BSDF"].inputs["Specular IOR Level"].default_value = 0.0
    panel = add_mesh(scene, "plane", "Panel", PANEL_CENTER, (PANEL_SIZE[0], PANEL_SIZE[1], 1.0), panel_material,
                     rotation=(1.5707963, 0.0, 0.0))
    panel.scale = (PANEL_SIZE[0], PANEL_SIZE[1], 1.0)
    add_mesh(scene, "cube", "Cube", (2.0, 2.0, 0.6), 0.6,
             principled("Diffuse", base_color=(0.2, 0.7, 0.3), roughness=0.8))
    lamp = bpy.data.lights.new("Lamp", "POINT")
    lamp.energy = 60.0
    lamp.shadow_soft_size = 0.15
    lamp_object = bpy.data.objects.new("Lamp", lamp)
    scene.collection.objects.link(lamp_object)
    lamp_object.location = LAMP_LOCATION
    add_camera(scene, (0.0, -6.0, 1.8), (0.0, 3.0, 0.4))
    scene.cycles.use_denoising = False  # truth and passes alike, nothing smoothed away
