"""A wet street with roughness from a noise texture, camera still.

The asphalt is a dark dielectric whose Principled roughness comes from a Noise
Texture mapped to 0.03..0.35, so puddle-like sharp patches sit next to blurry
ones: the per-pixel roughness varies across the floor and SSR must follow it
(short, sharp reflections in the puddles, wide blur elsewhere, and only the
Fresnel-weak reflection of a non-metal). Boxy buildings line both sides, with
emissive windows and lamps as bright targets, under a dim blue night sky.
"""
import bpy

from _common import add_camera, add_mesh, principled, set_render, set_world


def wet_asphalt():
    material = principled("WetAsphalt", base_color=(0.05, 0.05, 0.05), roughness=0.2)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    geometry = nodes.new("ShaderNodeNewGeometry")  # world position: the plane is scaled unevenly
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 0.5
    noise.inputs["Detail"].default_value = 4.0
    map_range = nodes.new("ShaderNodeMapRange")
    map_range.inputs["From Min"].default_value = 0.35
    map_range.inputs["From Max"].default_value = 0.65
    map_range.inputs["To Min"].default_value = 0.03
    map_range.inputs["To Max"].default_value = 0.35
    map_range.clamp = True
    links.new(geometry.outputs["Position"], noise.inputs["Vector"])
    links.new(noise.outputs["Fac"], map_range.inputs["Value"])
    links.new(map_range.outputs["Result"], nodes["Principled BSDF"].inputs["Roughness"])
    return material


def build(scene):
    set_render(scene, 320, 180)
    set_world(scene, (0.05, 0.08, 0.18), strength=0.5)
    add_mesh(scene, "plane", "Street", (0, 12, 0), (5.0, 16.0, 1.0), wet_asphalt())
    buildings = ((0.45, 0.3, 0.25), (0.3, 0.35, 0.45), (0.5, 0.45, 0.35), (0.25, 0.35, 0.3))
    window = principled("Window", base_color=(0, 0, 0), roughness=1.0,
                        emission=(1.0, 0.75, 0.4), emission_strength=5.0)
    for side in (-1, 1):
        for index in range(4):
            y = 3.0 + 5.0 * index + (1.5 if side > 0 else 0.0)
            height = (3.0, 4.5, 2.5, 4.0)[(index + (side > 0)) % 4]
            color = buildings[(index + 2 * (side > 0)) % 4]
            add_mesh(scene, "cube", f"Building{side:+d}{index}", (side * 4.0, y, height), (1.0, 2.2, height),
                     principled(f"Building{side:+d}{index}", base_color=color, roughness=0.8))
            add_mesh(scene, "cube", f"Window{side:+d}{index}", (side * 2.98, y, 1.6), (0.02, 0.9, 0.5), window)
    lamp = principled("Lamp", base_color=(0, 0, 0), roughness=1.0,
                      emission=(0.7, 0.85, 1.0), emission_strength=5.0)
    for index, (x, y) in enumerate(((-2.4, 6.0), (2.4, 12.0))):
        add_mesh(scene, "cylinder", f"Pole{index}", (x, y, 1.5), (0.05, 0.05, 1.5),
                 principled(f"Pole{index}", base_color=(0.1, 0.1, 0.1), roughness=0.5))
        globe = add_mesh(scene, "uv_sphere", f"Lamp{index}", (x, y, 3.1), 0.2, lamp, segments=16, ring_count=8)
        globe.visible_shadow = False
        # A real light inside each globe, so EEVEE lights the street as Cycles' emissive globe would.
        light = bpy.data.lights.new(f"LampLight{index}", "POINT")
        light.energy = 150.0
        light.color = (0.8, 0.9, 1.0)
        light.shadow_soft_size = 0.15
        light_object = bpy.data.objects.new(f"LampLight{index}", light)
        scene.collection.objects.link(light_object)
        light_object.location = (x, y, 3.1)
    add_mesh(scene, "cube", "EndBuilding", (0.0, 28.0, 4.0), (3.0, 0.5, 4.0),
             principled("EndBuilding", base_color=(0.35, 0.3, 0.3), roughness=0.8))
    add_mesh(scene, "cube", "EndWindow", (0.0, 27.48, 2.5), (1.2, 0.02, 0.6), window)
    add_camera(scene, (0.4, -1.5, 1.7), (0.0, 14.0, 0.0), lens=28.0)
    scene.frame_start = 1
    scene.frame_end = 8
