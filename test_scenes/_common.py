"""Small helpers shared by the scene builders (not a scene itself)."""
import math

import bpy
from mathutils import Vector


def principled(name, base_color=(0.8, 0.8, 0.8), roughness=0.5, metallic=0.0,
               emission=(0.0, 0.0, 0.0), emission_strength=0.0):
    material = bpy.data.materials.new(name)
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*base_color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
    bsdf.inputs["Emission Strength"].default_value = emission_strength
    return material


def add_mesh(scene, kind, name, location, size, material, **kwargs):
    """Add a primitive mesh ('cube', 'plane', 'uv_sphere', 'cylinder') with one material."""
    operator = getattr(bpy.ops.mesh, f"primitive_{kind}_add")
    operator(location=location, **kwargs)
    obj = bpy.context.active_object
    obj.name = name
    obj.scale = size if isinstance(size, (tuple, list)) else (size, size, size)
    obj.data.materials.append(material)
    if kind in ("uv_sphere", "cylinder"):
        for polygon in obj.data.polygons:
            polygon.use_smooth = True
    return obj


def add_camera(scene, location, target, lens=35.0):
    data = bpy.data.cameras.new("Camera")
    data.lens = lens
    data.clip_start = 0.1
    data.clip_end = 100.0
    camera = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(camera)
    camera.location = location
    direction = Vector(target) - Vector(location)
    camera.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera
    return camera


def add_sun(scene, rotation_degrees, strength=3.0):
    data = bpy.data.lights.new("Sun", "SUN")
    data.energy = strength
    sun = bpy.data.objects.new("Sun", data)
    scene.collection.objects.link(sun)
    sun.rotation_euler = [math.radians(a) for a in rotation_degrees]
    return sun


def set_world(scene, color, strength=1.0):
    world = bpy.data.worlds.new("World")
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    scene.world = world
    return world


def set_render(scene, width, height):
    """Resolution and samples: the add-on renders with the scene's own unless told otherwise."""
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.eevee.taa_render_samples = 16
    scene.cycles.samples = 128


def animate_location(scene, obj, locations, first_frame=1):
    """Key OBJ at each location on consecutive frames and make them the scene's frame range.

    Every rendered frame is a key, so the interpolation between keys never matters.
    """
    for offset, location in enumerate(locations):
        obj.location = location
        obj.keyframe_insert("location", frame=first_frame + offset)
    scene.frame_start = first_frame
    scene.frame_end = first_frame + len(locations) - 1
    scene.frame_set(first_frame)


def stability_stage(scene, floor_roughness=0.05):
    """What the stability cases share: 160x90, a blue-grey world and a metal mirror floor."""
    set_render(scene, 160, 90)
    set_world(scene, (0.25, 0.3, 0.4))
    return add_mesh(scene, "plane", "Floor", (0, 0, 0), 10.0,
                    principled("Mirror", base_color=(0.9, 0.9, 0.9), roughness=floor_roughness, metallic=1.0))
