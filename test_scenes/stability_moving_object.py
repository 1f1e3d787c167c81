"""A moving object: an emissive block slides across a mirror floor in front of a static camera.

Where the block was, the history holds its old reflection; the temporal
filter must let it go instead of leaving a trail.
"""
from _common import add_camera, add_mesh, animate_location, principled, stability_stage

MOTION = "object"


def build(scene):
    stability_stage(scene)
    add_mesh(scene, "cube", "Backdrop", (0.0, 4.0, 1.0), (2.5, 0.1, 1.0),
             principled("Backdrop", base_color=(0.6, 0.6, 0.6), roughness=0.8))
    block = add_mesh(scene, "cube", "Block", (0.0, 2.5, 0.4), (0.3, 0.3, 0.4),
                     principled("Block", base_color=(0, 0, 0), emission=(1.0, 0.4, 0.1), emission_strength=3.0))
    animate_location(scene, block, [(-1.2 + 0.8 * frame, 2.5, 0.4) for frame in range(4)])
    add_camera(scene, (0.0, -3.0, 1.3), (0.0, 3.0, 0.3), lens=30.0)
