"""Metal spheres of rising roughness (0.05, 0.25, 0.45, 0.7) in front of a striped backdrop.

The floor is a mirror, so each sphere's reflection is sharp while the spheres'
own reflections blur with roughness; past max_roughness SSR must leave the
probe/world reflection alone.
"""
from _common import add_camera, add_mesh, add_sun, principled, set_render, set_world

ROUGHNESS = (0.05, 0.25, 0.45, 0.7)


def build(scene):
    set_render(scene, 320, 180)
    set_world(scene, (0.3, 0.35, 0.45), strength=0.5)
    add_mesh(scene, "plane", "Floor", (0, 0, 0), 10.0,
             principled("Floor", base_color=(0.8, 0.8, 0.8), roughness=0.02, metallic=1.0))
    for index, color in enumerate(((0.9, 0.1, 0.1), (0.9, 0.9, 0.9), (0.1, 0.2, 0.9), (0.9, 0.9, 0.9),
                                   (0.1, 0.8, 0.2))):
        add_mesh(scene, "cube", f"Backdrop{index}", (-4 + 2 * index, 4.0, 1.5), (1.0, 0.1, 1.5),
                 principled(f"Backdrop{index}", base_color=color, roughness=0.8))
    for index, roughness in enumerate(ROUGHNESS):
        add_mesh(scene, "uv_sphere", f"Sphere{index}", (-2.25 + 1.5 * index, 1.0, 0.6), 0.6,
                 principled(f"Metal{index}", base_color=(0.95, 0.8, 0.6), roughness=roughness, metallic=1.0))
    add_sun(scene, (40, 0, 200), strength=2.0)
    add_camera(scene, (0.0, -6.0, 2.0), (0.0, 1.5, 0.6), lens=40.0)
