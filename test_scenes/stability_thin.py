"""Thin geometry: poles and a rail, a few pixels wide, over a slightly rough mirror floor.

A march whose steps are wider than the poles steps over them; a stochastic
march then hits them in some frames and misses them in others (flicker).
"""
from _common import add_camera, add_mesh, principled, stability_stage

MOTION = None


def build(scene):
    stability_stage(scene, floor_roughness=0.15)
    bright = principled("Rail", base_color=(0, 0, 0), emission=(1.0, 0.9, 0.6), emission_strength=4.0)
    for index, x in enumerate((-1.5, -0.5, 0.5, 1.5)):
        add_mesh(scene, "cylinder", f"Pole{index}", (x, 2.5, 0.6), (0.03, 0.03, 0.6), bright)
    add_mesh(scene, "cube", "Rail", (0.0, 2.5, 1.2), (1.6, 0.03, 0.03), bright)
    add_camera(scene, (0.0, -3.0, 1.5), (0.0, 2.5, 0.4), lens=30.0)
