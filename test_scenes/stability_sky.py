"""Sky hits: a mirror floor runs to the horizon under a bright sky, with one low block on it.

Most reflection rays leave through the sky, where the depth buffer holds
nothing: SSR must miss there and keep the world reflection, and must not
stretch the block's reflection into the sky's.
"""
from _common import add_camera, add_mesh, principled, set_render, set_world

MOTION = None


def build(scene):
    set_render(scene, 160, 90)
    set_world(scene, (0.4, 0.6, 1.0), strength=1.5)
    add_mesh(scene, "plane", "Floor", (0, 20, 0), 40.0,
             principled("Mirror", base_color=(0.9, 0.9, 0.9), roughness=0.05, metallic=1.0))
    add_mesh(scene, "cube", "Block", (0.8, 4.0, 0.3), 0.3,
             principled("Block", base_color=(0.8, 0.2, 0.1), roughness=0.6))
    add_camera(scene, (0.0, -2.0, 0.8), (0.0, 10.0, 0.6), lens=30.0)
