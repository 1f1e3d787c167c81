"""The analytic lamp split (lamp_split=analytic): lamp highlights computed from the scene's
lights, as EEVEE lights a surface with them, and split off EEVEE's "Specular Light", which holds
them and probe reflections together; SSR replaces only the latter.

The chain runs it as its first pass (gpu_passes.LAMP_SPLIT, lamp_split.glsl) when its inputs
carry LampLights: each lamp's radiance integrated against the GGX lobe normalised by its
reflectance (the FG table's A + B, the chain's one albedo), the quantity that pass holds (its
LTC integral; the pass is later multiplied by the split-sum specular colour), times EEVEE's
Shadow pass. The integral uses both a light-shape and a lobe strategy combined by multiple
importance sampling (power heuristic) on a fixed stratified pattern, so mirrors, rough
surfaces, small and large lights are all exact to sampling error. The lights themselves are
read from the scene by blender.lights.
"""
import math
from dataclasses import dataclass

import gpu
import numpy as np

from .uniforms import LAMP_BLOCK, LAMP_SHAPES

# 12x12 points per sampling strategy: within 2 % of a Monte Carlo integral over a highlight (test_analytic_lamps).
STRATA_PER_SIDE = 12


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
        "viewport_size": size, "background_depth": background_depth,
        "lamp_count": len(lamps), "strata_per_side": STRATA_PER_SIDE, "lamps": records}).tobytes())
