"""A chrome sphere over a roughness-0.12 metal floor in front of a checker wall.

The sphere is a curved mirror: neighbouring pixels reflect rays in quickly
diverging directions, so its reflection of the checker wall, the floor and the
coloured blocks is squeezed and distorted towards the rim, where rays graze
the surface and leave the screen. The floor below is slightly rough (0.12), so
its reflection of the sphere and the wall must blur, not stay sharp. The sun
shines from behind the camera, so its highlights fall mostly off the
reflective areas.
"""
from _common import add_camera, add_mesh, add_sun, principled, set_render, set_world

SPHERE_CENTER = (0.0, 1.5, 1.2)
SPHERE_RADIUS = 1.2


def checker_material(name, color1, color2, scale):
    """A diffuse Principled material whose base colour is a Checker Texture on the object's UVs."""
    material = principled(name, roughness=0.9)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    checker = nodes.new("ShaderNodeTexChecker")
    checker.inputs["Color1"].default_value = (*color1, 1.0)
    checker.inputs["Color2"].default_value = (*color2, 1.0)
    checker.inputs["Scale"].default_value = scale
    links.new(checker.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    return material


def build(scene):
    set_render(scene, 320, 180)
    set_world(scene, (0.25, 0.3, 0.4), strength=0.6)
    add_mesh(scene, "plane", "Floor", (0, 0, 0), 12.0,
             principled("MetalFloor", base_color=(0.85, 0.85, 0.85), roughness=0.12, metallic=1.0))
    add_mesh(scene, "plane", "CheckerWall", (0.0, 5.0, 3.0), (8.0, 3.0, 1.0),
             checker_material("Checker", (0.9, 0.9, 0.85), (0.08, 0.08, 0.1), scale=8.0),
             rotation=(1.5707963, 0.0, 0.0))
    add_mesh(scene, "uv_sphere", "ChromeSphere", SPHERE_CENTER, SPHERE_RADIUS,
             principled("Chrome", base_color=(0.95, 0.95, 0.95), roughness=0.02, metallic=1.0),
             segments=48, ring_count=24)
    for name, color, location, size in (("Red", (0.8, 0.05, 0.05), (-2.6, 2.5, 0.6), 0.6),
                                        ("Green", (0.05, 0.7, 0.1), (2.6, 2.8, 0.5), 0.5),
                                        ("Yellow", (0.9, 0.7, 0.05), (-2.4, 0.2, 0.35), 0.35),
                                        ("Blue", (0.05, 0.15, 0.85), (2.2, 0.0, 0.4), 0.4)):
        add_mesh(scene, "cube", f"Cube{name}", location, size,
                 principled(name, base_color=color, roughness=0.6))
    add_sun(scene, (55, 0, 200), strength=3.0)
    add_camera(scene, (0.0, -6.5, 3.0), (0.0, 1.8, 0.8), lens=30.0)
    scene.frame_start = 1
    scene.frame_end = 8
