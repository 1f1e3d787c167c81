"""Lamp highlights computed from the scene's lights, as EEVEE lights a surface with them.

EEVEE's "Specular Light" holds lamp highlights and probe reflections together; SSR
replaces only the latter, so the highlights must be split off. lamp_split=analytic
computes them here instead of rendering the lamps a second time (passes.py):

- `scene_lamps(scene)` reads every rendering light into a Lamp, following EEVEE's
  light set-up (eevee_light.cc): radiance from power, colour (temperature included),
  exposure and the shape's area; point and spot lights are spheres of the light's
  radius (with Soft Falloff a disk facing the surface), suns disks of their angle,
  area lights rectangles or ellipses; spot cones with blend, the distance fade of
  the light threshold or custom distance, and the fade below a surface's horizon.
  Lights it cannot model (light linking, square spots, more than MAX_LAMPS) are
  named, and lamp_split=analytic is refused for them in one line.
- `AnalyticLampLight` splits them off EEVEE's "Specular Light" on the GPU
  (lamp_split.glsl): each lamp's radiance integrated against the normalised GGX
  lobe, the quantity that pass holds (its LTC integral; the pass is later
  multiplied by the split-sum specular colour), times EEVEE's Shadow pass. The
  integral uses both a light-shape and a lobe strategy combined by multiple
  importance sampling (power heuristic) on a fixed stratified pattern, so
  mirrors, rough surfaces, small and large lights are all exact to sampling error.
  `lamp_specular` is the same integral unshadowed, read back (for tests).
"""
import functools
import math
from dataclasses import dataclass

import gpu
import numpy as np

from .errors import SSRError
from .gpu_backend import download, empty_texture, ensure_backend, upload
from .gpu_params import LAMP_BLOCK, MAX_LAMPS
from .shaders import get_pass

STRATA_PER_SIDE = 12  # 12x12 points per sampling strategy: within 2 % of a Monte Carlo integral over a highlight (test_analytic_lamps)
MIN_ALPHA = 2e-3  # GGX alpha floor: below it float32 cannot hold the peak of D
ALBEDO_TABLE_SIZE = 32


@dataclass(frozen=True)
class Lamp:
    name: str
    shape: str            # "sphere", "facing_disk", "sun", "rect" or "ellipse"
    radiance: tuple       # (r, g, b) W / (m^2 sr), specular factor included
    position: tuple       # world; for a sun, the unit direction towards it
    x_axis: tuple = (1.0, 0.0, 0.0)  # area lights: the emitter's own axes (it emits along -z)
    y_axis: tuple = (0.0, 1.0, 0.0)
    z_axis: tuple = (0.0, 0.0, 1.0)  # spot and area lights: the light's local z, world space
    half_size: tuple = (0.0, 0.0)    # area lights: half extents; spheres/disks: (radius, radius)
    influence_radius: float = math.inf  # local lights fade to nothing at this distance
    spot: tuple = None    # (spot_mul, spot_bias, size_inv_x, size_inv_y) for spot lights


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


def stratified_points(count):
    """COUNT points (a square number) at the centres of a stratified grid over [0, 1)^2."""
    side = int(round(math.sqrt(count)))
    return (np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), -1).reshape(-1, 2) + 0.5) / side


def _smith_lambda(cos_theta, alpha2):
    cos2 = np.clip(cos_theta * cos_theta, 1e-12, 1.0)
    return 0.5 * (np.sqrt(1 + alpha2 * (1 - cos2) / cos2) - 1)


def visible_normal_weight(n_dot_v, n_dot_l, alpha2):
    """Weight of a direction drawn from the visible normals (sample_visible_normals) in the
    normalised GGX lobe integral: the height-correlated Smith G2 over G1(view); 0 below the horizon."""
    lambda_v = _smith_lambda(n_dot_v, alpha2)
    return np.where(n_dot_l > 0, (1 + lambda_v) / (1 + lambda_v + _smith_lambda(n_dot_l, alpha2)), 0.0)


def sample_visible_normals(view, alpha, points):
    """Half vectors (..., S, 3) in the local frame (normal = z) drawn from the visible normals
    of an isotropic GGX lobe of ALPHA (..., 1) seen from VIEW (..., 1, 3) (Heitz 2018)."""
    stretched = np.concatenate([alpha[..., None] * view[..., :2], view[..., 2:]], -1)
    stretched = stretched / np.linalg.norm(stretched, axis=-1, keepdims=True)
    length2 = stretched[..., 0] ** 2 + stretched[..., 1] ** 2
    t1 = np.where(length2[..., None] > 0,
                  np.stack([-stretched[..., 1], stretched[..., 0], np.zeros_like(length2)], -1)
                  / np.sqrt(np.maximum(length2, 1e-24))[..., None], np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(stretched, t1)
    radius, phi = np.sqrt(points[:, 0]), 2 * math.pi * points[:, 1]
    p1, p2 = radius * np.cos(phi), radius * np.sin(phi)
    s = 0.5 * (1 + stretched[..., 2])
    p2 = (1 - s) * np.sqrt(1 - p1 * p1) + s * p2
    normal = (p1[..., None] * t1 + p2[..., None] * t2
              + np.sqrt(np.maximum(0, 1 - p1 * p1 - p2 * p2))[..., None] * stretched)
    half = np.concatenate([alpha[..., None] * normal[..., :2], np.maximum(normal[..., 2:], 1e-6)], -1)
    return half / np.linalg.norm(half, axis=-1, keepdims=True)


@functools.lru_cache(maxsize=1)
def albedo_table(size=ALBEDO_TABLE_SIZE, samples=1024):
    """(size, size) E(n.v, roughness) at texel centres, [n.v index, roughness index]: the GGX
    lobe's reflectance with F = 1, which normalises it, from its visible normals."""
    centres = (np.arange(size) + 0.5) / size
    n_dot_v, roughness = np.meshgrid(centres, centres, indexing="ij")
    view = np.stack([np.sqrt(1 - n_dot_v ** 2), np.zeros_like(n_dot_v), n_dot_v], -1)[..., None, :]
    alpha = np.maximum(roughness ** 2, MIN_ALPHA)[..., None]
    half = sample_visible_normals(view, alpha, stratified_points(samples))
    n_dot_l = (2 * np.sum(view * half, -1, keepdims=True) * half - view)[..., 2]
    return visible_normal_weight(view[..., 2], n_dot_l, alpha ** 2).mean(-1)


@functools.lru_cache(maxsize=1)
def _albedo_texture():
    """albedo_table as a texture, uploaded once (the GPU backend lives as long as the process).
    The table's rows are roughness and columns n.v; GL's first row is the image's last."""
    return upload(albedo_table().T[::-1])


_SHAPES = {"sphere": 0, "facing_disk": 1, "sun": 2, "rect": 3, "ellipse": 4}  # lamp_split.glsl's SHAPE_*


def lamp_block(lamps, size, view_matrix, projection_matrix, background_depth):
    """The LampBlock uniform buffer of LAMPS (at most MAX_LAMPS) for a SIZE (width, height) frame."""
    records = [{"position": lamp.position, "shape": _SHAPES[lamp.shape], "radiance": lamp.radiance,
                "influence_radius": min(lamp.influence_radius, 3e38), "x_axis": lamp.x_axis,
                "half_width": lamp.half_size[0], "y_axis": lamp.y_axis, "half_height": lamp.half_size[1],
                "z_axis": lamp.z_axis, "spot_mul": lamp.spot[0] if lamp.spot else 0.0,
                "spot_size_inv": lamp.spot[2:] if lamp.spot else (1.0, 1.0),
                "spot_bias": lamp.spot[1] if lamp.spot else 1.0, "is_spot": int(lamp.spot is not None)}
               for lamp in lamps]
    return gpu.types.GPUUniformBuf(LAMP_BLOCK.pack({
        "clip_to_view": np.linalg.inv(np.asarray(projection_matrix, np.float64)),
        "view_to_world": np.linalg.inv(np.asarray(view_matrix, np.float64)),
        "viewport_size": size, "background_depth": background_depth, "min_alpha": MIN_ALPHA,
        "lamp_count": len(lamps), "strata_per_side": STRATA_PER_SIDE, "lamps": records}).tobytes())


@dataclass(frozen=True, eq=False)
class AnalyticLampLight:
    """EEVEE's lamp highlights left to the GPU (lamp_split=analytic): LAMPS (scene_lamps) on
    a frame's surfaces, seen through VIEW_MATRIX and PROJECTION_MATRIX, shadowed by SHADOW
    (EEVEE's Shadow pass, (H, W)). The chain splits them off the specular light on the GPU,
    from the textures it uploads anyway (`split`); numpy callers get them read back
    (FramePasses.specular_direct)."""
    lamps: list
    shadow: np.ndarray
    view_matrix: np.ndarray
    projection_matrix: np.ndarray
    background_depth: float

    def split(self, depth_tx, normal_tx, roughness_tx, specular_light_tx):
        """(specular direct, specular indirect) textures: the lamps' shadowed specular light and
        the rest of SPECULAR_LIGHT_TX, on the surfaces of DEPTH_TX, NORMAL_TX (world) and
        ROUGHNESS_TX."""
        size = (depth_tx.width, depth_tx.height)
        direct_tx, indirect_tx = empty_texture(size), empty_texture(size)
        get_pass("lamp_split").draw(
            [direct_tx, indirect_tx],
            samplers=(("depth_tx", depth_tx), ("normal_tx", normal_tx), ("roughness_tx", roughness_tx),
                      ("albedo_tx", _albedo_texture()), ("specular_light_tx", specular_light_tx),
                      ("shadow_tx", upload(self.shadow))),
            uniform_blocks=(("lamp_block", lamp_block(self.lamps, size, self.view_matrix, self.projection_matrix,
                                                      self.background_depth)),))
        return direct_tx, indirect_tx


def lamp_specular(lamps, depth, normal, roughness, view_matrix, projection_matrix, background_depth):
    """(H, W, 3) unshadowed specular light of LAMPS on the surfaces of a frame (DEPTH, world
    NORMAL, ROUGHNESS in image order; the camera's matrices), drawn on the GPU."""
    ensure_backend()
    light = AnalyticLampLight(lamps, np.ones_like(depth), view_matrix, projection_matrix, background_depth)
    direct_tx, _ = light.split(upload(depth), upload(normal), upload(roughness), upload(np.zeros_like(normal)))
    return download(direct_tx, 3)


def require_modelled(unmodelled):
    """Refuse lamp_split=analytic for lights it cannot model, in one line."""
    if unmodelled:
        raise SSRError(f"lamp_split=analytic cannot model every light ({'; '.join(unmodelled)}): "
                       "use auto, render or unshadowed")
