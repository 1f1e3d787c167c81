"""A glossy corridor: a polished floor between two walls with emissive stripes.

Reflections run a long way down the corridor and towards the vanishing point,
where a linear march needs many steps; the stripes give sharp, bright targets.
"""
from _common import add_camera, add_mesh, principled, set_render, set_world


def build(scene):
    set_render(scene, 320, 180)
    set_world(scene, (0.02, 0.02, 0.03))
    floor = principled("PolishedFloor", base_color=(0.6, 0.6, 0.65), roughness=0.08, metallic=0.9)
    wall = principled("Wall", base_color=(0.5, 0.45, 0.4), roughness=0.7)
    add_mesh(scene, "cube", "Floor", (0, 10, -0.05), (2.0, 12.0, 0.05), floor)
    add_mesh(scene, "cube", "WallLeft", (-2.05, 10, 1.5), (0.05, 12.0, 1.5), wall)
    add_mesh(scene, "cube", "WallRight", (2.05, 10, 1.5), (0.05, 12.0, 1.5), wall)
    add_mesh(scene, "cube", "EndWall", (0, 22, 1.5), (2.0, 0.05, 1.5),
             principled("EndWall", base_color=(0.1, 0.3, 0.8), roughness=0.5))
    for index, y in enumerate(range(2, 22, 4)):
        color = ((1.0, 0.9, 0.7), (0.7, 0.9, 1.0))[index % 2]
        stripe = principled(f"Stripe{index}", base_color=(0, 0, 0), roughness=1.0,
                            emission=color, emission_strength=6.0)
        add_mesh(scene, "cube", f"StripeLeft{index}", (-1.98, y, 1.6), (0.02, 0.3, 1.2), stripe)
        add_mesh(scene, "cube", f"StripeRight{index}", (1.98, y + 2, 1.6), (0.02, 0.3, 1.2), stripe)
    add_camera(scene, (0.3, -1.0, 1.4), (0.0, 12.0, 0.6), lens=24.0)
