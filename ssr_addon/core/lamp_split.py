"""The analytic lamp split (lamp_split=analytic): lamp highlights computed from the scene's
lights, as EEVEE lights a surface with them, and split off EEVEE's "Specular Light", which holds
them and probe reflections together; SSR replaces only the latter.

The chain runs it as its first pass (gpu_passes.LAMP_SPLIT, lamp_split.glsl) when its inputs
carry LampLights: each lamp's radiance integrated against the normalised GGX lobe, the quantity
that pass holds (its LTC integral; the pass is later multiplied by the split-sum specular
colour), times EEVEE's Shadow pass. The integral uses both a light-shape and a lobe strategy
combined by multiple importance sampling (power heuristic) on a fixed stratified pattern, so
mirrors, rough surfaces, small and large lights are all exact to sampling error. The lights
themselves are read from the scene by blender.lights.
"""
import functools
import math
from dataclasses import dataclass

import gpu
import numpy as np

from .ggx import sample_visible_normals, stratified_points, visible_normal_weight
from .gpu_backend import upload
from .uniforms import LAMP_BLOCK, LAMP_SHAPES

# 12x12 points per sampling strategy: within 2 % of a Monte Carlo integral over a highlight (test_analytic_lamps).
STRATA_PER_SIDE = 12
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


@dataclass(frozen=True, eq=False)
class LampLights:
    """What the chain's lamp split needs of a frame: its LAMPS (Lamp, at most uniforms.MAX_LAMPS)
    and SHADOW, EEVEE's Shadow pass ((H, W), each pixel's shadowed share of all its lamp light:
    exact for one lamp, a lamp-weighted mean for more)."""
    lamps: tuple
    shadow: np.ndarray


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
def albedo_texture():
    """albedo_table as a texture, uploaded once (the GPU backend lives as long as the process).
    The table's rows are roughness and columns n.v; GL's first row is the image's last."""
    return upload(albedo_table().T[::-1])


def lamp_block(lamps, size, view_matrix, projection_matrix, background_depth):
    """The LampBlock uniform buffer of LAMPS (at most MAX_LAMPS) for a SIZE (width, height) frame."""
    records = [{"position": lamp.position, "shape": LAMP_SHAPES[lamp.shape], "radiance": lamp.radiance,
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
