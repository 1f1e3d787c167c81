"""A mirror floor under a floating slab whose underside glows green: the camera sees only the
slab's white top, so the green shows only in the floor's reflection. Screen space cannot show
it (the ray passes behind the slab's top); a planar capture of the floor can.

SLAB_CENTER and SLAB_HALF_SIZE give the underside's rectangle, so tests can project its mirror
image analytically.
"""
import math

from _common import add_camera, add_mesh, add_sun, principled, set_render, set_world

SLAB_CENTER = (0.0, 1.0, 1.0)
SLAB_HALF_SIZE = 1.2
UNDERSIDE_GAP = 0.02  # the glowing face sits this far below the top


def build(scene):
    set_render(scene, 320, 180)
    set_world(scene, (0.05, 0.06, 0.08))
    mirror = principled("Mirror", base_color=(0.95, 0.95, 0.95), roughness=0.0, metallic=1.0)
    add_mesh(scene, "plane", "Floor", (0, 0, 0), 12.0, mirror)
    add_mesh(scene, "plane", "SlabTop", SLAB_CENTER, SLAB_HALF_SIZE, principled("Top", roughness=0.8))
    glow = principled("Underside", base_color=(0, 0, 0), roughness=1.0, emission=(0.1, 1.0, 0.2),
                      emission_strength=2.0)
    x, y, z = SLAB_CENTER
    add_mesh(scene, "plane", "SlabUnderside", (x, y, z - UNDERSIDE_GAP), SLAB_HALF_SIZE, glow,
             rotation=(math.pi, 0.0, 0.0))
    add_sun(scene, (50, 0, 180), strength=3.0)
    add_camera(scene, (0.0, -7.0, 2.5), (0.0, 2.0, 0.3))
