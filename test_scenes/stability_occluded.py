"""Reflected geometry hidden behind a foreground object.

A hanging board near the camera covers the lower middle of an emissive back
panel; the mirror floor in front of the panel reflects exactly that covered
part, which the depth buffer does not hold. SSR must not reflect the board in
its place or smear the panel's visible edges into it.
"""
from _common import add_camera, add_mesh, principled, stability_stage

MOTION = None


def build(scene):
    stability_stage(scene)
    add_mesh(scene, "cube", "Panel", (0.0, 4.0, 1.0), (2.0, 0.05, 1.0),
             principled("Panel", base_color=(0, 0, 0), emission=(1.0, 0.5, 0.1), emission_strength=3.0))
    add_mesh(scene, "cube", "Board", (0.0, -0.5, 1.0), (0.35, 0.02, 0.3),
             principled("Board", base_color=(0.05, 0.05, 0.05), roughness=0.8))
    add_camera(scene, (0.0, -3.0, 1.3), (0.0, 4.0, 0.4), lens=30.0)
