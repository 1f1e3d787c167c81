"""A moving camera: it slides sideways over a mirror floor with coloured emissive blocks.

Under camera motion the reflections move differently from the floor they lie
on, so a temporal filter that reprojects the surface point smears them
(ghosting); reprojecting the hit point keeps them in place.
"""
from _common import add_camera, add_mesh, animate_location, principled, stability_stage

MOTION = "camera"


def build(scene):
    stability_stage(scene)
    for index, (x, color) in enumerate(((-1.2, (1.0, 0.3, 0.1)), (0.0, (0.2, 0.9, 0.3)), (1.2, (0.2, 0.4, 1.0)))):
        add_mesh(scene, "cube", f"Block{index}", (x, 3.0, 0.4), (0.3, 0.3, 0.4),
                 principled(f"Block{index}", base_color=(0, 0, 0), emission=color, emission_strength=3.0))
    camera = add_camera(scene, (0.0, -3.0, 1.3), (0.0, 3.0, 0.3), lens=30.0)
    animate_location(scene, camera, [(-0.3 + 0.2 * frame, -3.0, 1.3) for frame in range(4)])
