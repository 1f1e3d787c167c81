"""Rays towards the camera: a mirror wall faces the camera with an emissive sphere in between.

The wall's reflection of the sphere shows the sphere's back, which the camera
never sees, and its rays run back towards the camera: SSR must fade them out
(camera-facing fade) rather than reflect the sphere's front.
"""
from _common import add_camera, add_mesh, principled, set_render, set_world

MOTION = None


def build(scene):
    set_render(scene, 160, 90)
    set_world(scene, (0.25, 0.3, 0.4))
    add_mesh(scene, "plane", "Floor", (0, 0, 0), 10.0, principled("Floor", base_color=(0.5, 0.5, 0.5), roughness=0.9))
    add_mesh(scene, "cube", "MirrorWall", (0.0, 3.0, 1.5), (3.0, 0.05, 1.5),
             principled("Mirror", base_color=(0.9, 0.9, 0.9), roughness=0.05, metallic=1.0))
    add_mesh(scene, "uv_sphere", "Sphere", (0.4, 1.2, 0.8), 0.4,
             principled("Sphere", base_color=(0, 0, 0), emission=(1.0, 0.3, 0.1), emission_strength=3.0))
    add_camera(scene, (-1.5, -2.5, 1.4), (0.5, 3.0, 1.0), lens=30.0)
