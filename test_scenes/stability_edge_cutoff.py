"""Rays leaving the screen: emissive pillars stand on a mirror floor and run out of the top of the frame.

Floor pixels near the bottom of the frame reflect the pillars' upper parts,
which are above the screen, so their rays leave it: SSR must fade towards the
screen border into the world reflection instead of cutting off.
"""
from _common import add_camera, add_mesh, principled, stability_stage

MOTION = None


def build(scene):
    stability_stage(scene)
    for index, (x, color) in enumerate(((-1.6, (1.0, 0.4, 0.1)), (0.0, (0.2, 0.9, 0.3)), (1.6, (0.2, 0.4, 1.0)))):
        add_mesh(scene, "cube", f"Pillar{index}", (x, 2.3, 2.5), (0.3, 0.3, 2.5),
                 principled(f"Pillar{index}", base_color=(0, 0, 0), emission=color, emission_strength=3.0))
    add_camera(scene, (0.0, -3.0, 2.0), (0.0, 2.3, 0.0), lens=28.0)
