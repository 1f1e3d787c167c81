"""The scene's lights as the analytic lamp split models them (core.lamp_split.Lamp), read as
EEVEE sets its lights up (eevee_light.cc): radiance from power, colour (temperature
included), exposure and the shape's area; point and spot lights are spheres of the light's
radius (with Soft Falloff a disk facing the surface), suns disks of their angle, area lights
rectangles or ellipses; spot cones with blend, the distance fade of the light threshold or
custom distance. Lights it cannot model (light linking, square spots, more than MAX_LAMPS)
are named, and lamp_split=analytic is refused for them in one line.
"""
import math

import numpy as np

from ..core.errors import SSRError
from ..core.lamp_split import Lamp
from ..core.uniforms import MAX_LAMPS


def _renders(obj):
    return not obj.hide_render and not any(collection.hide_render for collection in obj.users_collection)


def _light_colour(light):
    colour = np.array(light.color, np.float64)
    if light.use_temperature:
        colour = colour * np.array(light.temperature_color, np.float64)
    return colour


def scene_lamps(scene):
    """(lamps, unmodelled) of SCENE: a Lamp for every light that renders and reflects,
    and a line for each light that lamp_specular cannot reproduce."""
    lamps, unmodelled = [], []
    threshold = max(scene.eevee.light_threshold, 1e-16)
    for obj in scene.objects:
        if obj.type != "LIGHT" or not _renders(obj):
            continue
        light = obj.data
        if light.specular_factor <= 0 or not obj.visible_glossy:
            continue
        if obj.light_linking.receiver_collection is not None or obj.light_linking.blocker_collection is not None:
            unmodelled.append(f"'{obj.name}' uses light linking")
            continue
        if light.type == "SPOT" and light.use_square:
            unmodelled.append(f"'{obj.name}' is a square spot")
            continue
        lamps.append(_lamp(obj, light, threshold))
    if len(lamps) > MAX_LAMPS:
        unmodelled.append(f"{len(lamps)} lights, more than the {MAX_LAMPS} it models at once")
    return lamps, unmodelled


def _lamp(obj, light, threshold):
    matrix = np.array(obj.matrix_world, np.float64)
    scale = np.linalg.norm(matrix[:3, :3], axis=0)
    axes = matrix[:3, :3] / np.maximum(scale, 1e-12)
    if np.dot(np.cross(axes[:, 0], axes[:, 1]), axes[:, 2]) < 0:
        axes[:, 1] = -axes[:, 1]  # consistent handedness under a negative scale, as EEVEE
    power = light.energy * 2.0 ** light.exposure
    colour = _light_colour(light)
    common = dict(name=obj.name, position=tuple(matrix[:3, 3]), x_axis=tuple(axes[:, 0]),
                  y_axis=tuple(axes[:, 1]), z_axis=tuple(axes[:, 2]))
    if light.type == "SUN":
        half_angle = min(light.angle, math.radians(179.9)) / 2
        radius = min(max(math.tan(half_angle), 1e-3), 20.0)
        radiance = power * (1 + 1 / radius ** 2) / math.pi  # irradiance to radiance
        return Lamp(shape="sun", radiance=tuple(colour * radiance * light.specular_factor),
                    half_size=(radius, radius), **dict(common, position=tuple(axes[:, 2])))
    max_power = colour.max() * abs(power / 100) * max(light.diffuse_factor, light.specular_factor)
    influence = light.cutoff_distance if light.use_custom_distance else math.sqrt(max_power / threshold)
    if light.type == "AREA":
        half = np.array([light.size, light.size_y if light.shape in ("RECTANGLE", "ELLIPSE") else light.size])
        half = np.maximum(half * scale[:2] / 2, 3e-3)
        ellipse = light.shape in ("DISK", "ELLIPSE")
        area = 4 * half[0] * half[1] * (math.pi / 4 if ellipse else 1)
        if not light.normalize:
            power *= area
        return Lamp(shape="ellipse" if ellipse else "rect", half_size=tuple(half),
                    radiance=tuple(colour * power / (math.pi * area) * light.specular_factor),
                    influence_radius=influence, **common)
    radius = max(light.shadow_soft_size, 1e-3)
    area = 4 * math.pi * radius ** 2
    if not light.normalize:
        power *= area
    spot = None
    if light.type == "SPOT":
        cos_size = math.cos(light.spot_size / 2)
        spot_mul = 1 / max(1e-8, (1 - cos_size) * light.spot_blend)
        size_inv = scale[2] / np.maximum(scale[:2], 1e-8)
        spot = (spot_mul, -cos_size * spot_mul, size_inv[0], size_inv[1])
    return Lamp(shape="facing_disk" if light.use_soft_falloff else "sphere", half_size=(radius, radius),
                radiance=tuple(colour * power / (math.pi * area) * light.specular_factor),
                influence_radius=influence, spot=spot, **common)


def require_modelled(unmodelled):
    """Refuse lamp_split=analytic for lights it cannot model, in one line."""
    if unmodelled:
        raise SSRError(f"lamp_split=analytic cannot model every light ({'; '.join(unmodelled)}): "
                       "use auto, render or unshadowed")
