"""A perfect mirror floor under coloured cubes and one emissive marker.

The marker's position is known (MARKER_CENTER) so tests can project its mirror
image analytically. The sun shines from behind the camera, so its highlight on
the mirror is off screen and the floor shows only reflections.
"""
from _common import add_camera, add_mesh, add_sun, principled, set_render, set_world

MARKER_CENTER = (0.0, 3.0, 1.2)
MARKER_RADIUS = 0.35


def build(scene):
    set_render(scene, 320, 180)
    set_world(scene, (0.05, 0.06, 0.08))
    mirror = principled("Mirror", base_color=(0.95, 0.95, 0.95), roughness=0.0, metallic=1.0)
    add_mesh(scene, "plane", "Floor", (0, 0, 0), 12.0, mirror)
    for name, color, x in (("Red", (0.8, 0.05, 0.05), -2.2),
                           ("Green", (0.05, 0.8, 0.05), 0.0),
                           ("Blue", (0.05, 0.05, 0.8), 2.2)):
        add_mesh(scene, "cube", f"Cube{name}", (x, 5.0, 0.5), 0.5,
                 principled(name, base_color=color, roughness=0.6))
    marker = principled("Marker", base_color=(0, 0, 0), roughness=1.0,
                        emission=(1.0, 0.6, 0.1), emission_strength=4.0)
    add_mesh(scene, "uv_sphere", "Marker", MARKER_CENTER, MARKER_RADIUS, marker)
    add_sun(scene, (50, 0, 180), strength=3.0)
    add_camera(scene, (0.0, -7.0, 2.5), (0.0, 3.0, 0.3))
