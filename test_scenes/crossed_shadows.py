"""A lamp's highlight inside another lamp's shadow: where lamp_split=unshadowed is not exact.

A low sun throws a wall's shadow across a glossy half-metal floor, and a point lamp's
highlight on the floor lies inside that shadow. EEVEE's Shadow pass is one
number per pixel, the shadowed share of all lamp light there; in the shadow it
is mostly the sun's diffuse light that is missing, so the share is small, and
an unshadowed lamp render times that share dims the point lamp's highlight,
which no shadow touches. benchmarks/lamp_split.py measures how much.
"""
import bpy
from _common import add_camera, add_mesh, add_sun, principled, set_render, set_world


def build(scene):
    set_render(scene, 320, 180)
    set_world(scene, (0.3, 0.35, 0.45), strength=0.3)
    add_mesh(scene, "plane", "Floor", (0, 0, 0), 10.0,
             principled("Floor", base_color=(0.6, 0.6, 0.6), roughness=0.15, metallic=0.5))
    add_mesh(scene, "cube", "Wall", (-2.0, 2.0, 1.0), (0.1, 3.0, 1.0),
             principled("Wall", base_color=(0.8, 0.3, 0.2), roughness=0.6))
    add_sun(scene, (0, -70, 0), strength=4.0)
    lamp = bpy.data.lights.new("Lamp", "POINT")
    lamp.energy = 100.0
    lamp.shadow_soft_size = 0.1
    lamp_object = bpy.data.objects.new("Lamp", lamp)
    scene.collection.objects.link(lamp_object)
    lamp_object.location = (0.0, 3.0, 1.5)
    add_camera(scene, (0.0, -4.0, 2.0), (0.0, 1.5, 0.0), lens=35.0)
