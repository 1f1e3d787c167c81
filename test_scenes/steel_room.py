"""A closed room seen from above over a polished steel floor: its glowing checker ceiling and
the upper half of its walls lie above the frame, so the floor's reflection of them is what no
screen-space method can see (the issue's "closed room" scene). The floor meets the far wall in
a one-pixel contact line, where a self-intersection shows as a dark seam.
"""
import bpy

from _common import add_camera, add_mesh, principled, set_render, set_world

ROOM_HALF = 4.0
ROOM_HEIGHT = 3.0


def checker(name, colour_a, colour_b, scale, emission_strength=0.0, roughness=0.6):
    material = principled(name, roughness=roughness)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    bsdf = nodes["Principled BSDF"]
    pattern = nodes.new("ShaderNodeTexChecker")
    pattern.inputs["Scale"].default_value = scale
    pattern.inputs["Color1"].default_value = (*colour_a, 1.0)
    pattern.inputs["Color2"].default_value = (*colour_b, 1.0)
    coordinates = nodes.new("ShaderNodeTexCoord")
    links.new(coordinates.outputs["Object"], pattern.inputs["Vector"])
    links.new(pattern.outputs["Color"], bsdf.inputs["Emission Color" if emission_strength else "Base Color"])
    if emission_strength:
        bsdf.inputs["Emission Strength"].default_value = emission_strength
        bsdf.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    return material


def build(scene):
    set_render(scene, 320, 180)
    set_world(scene, (0.01, 0.01, 0.015))
    steel = principled("Steel", base_color=(0.85, 0.85, 0.88), roughness=0.04, metallic=1.0)
    add_mesh(scene, "plane", "Floor", (0, 0, 0), ROOM_HALF, steel)
    ceiling = checker("Ceiling", (1.0, 0.85, 0.6), (0.05, 0.05, 0.08), 1.0, emission_strength=3.0)
    add_mesh(scene, "plane", "Ceiling", (0, 0, ROOM_HEIGHT), ROOM_HALF, ceiling, rotation=(3.14159265, 0, 0))
    # (location, rotation, size, colour): each plane's local x runs along the floor (back and front
    # walls) or up the wall (the sides, turned about y), so their sizes differ.
    along, up = (ROOM_HALF, ROOM_HEIGHT / 2, 1.0), (ROOM_HEIGHT / 2, ROOM_HALF, 1.0)
    walls = {"WallBack": ((0, ROOM_HALF, ROOM_HEIGHT / 2), (1.5708, 0, 0), along, (0.2, 0.35, 0.8)),
             "WallFront": ((0, -ROOM_HALF, ROOM_HEIGHT / 2), (-1.5708, 0, 0), along, (0.7, 0.7, 0.7)),
             "WallLeft": ((-ROOM_HALF, 0, ROOM_HEIGHT / 2), (0, 1.5708, 0), up, (0.8, 0.25, 0.2)),
             "WallRight": ((ROOM_HALF, 0, ROOM_HEIGHT / 2), (0, -1.5708, 0), up, (0.25, 0.7, 0.3))}
    for name, (location, rotation, size, colour) in walls.items():
        wall = checker(name, colour, tuple(0.3 * c for c in colour), 2.0)
        add_mesh(scene, "plane", name, location, size, wall, rotation=rotation)
    light = bpy.data.lights.new("RoomLight", "POINT")
    light.energy = 300.0
    lamp = bpy.data.objects.new("RoomLight", light)
    scene.collection.objects.link(lamp)
    lamp.location = (0.0, 0.0, ROOM_HEIGHT - 0.4)
    add_camera(scene, (0.0, -3.6, 2.6), (0.0, 1.5, 0.0), lens=30.0)
