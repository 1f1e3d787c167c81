"""The GGX lobe: the alpha floor every pass and estimate shares (ggx_lib.glsl is compiled with
it), and in numpy visible-normal sampling (Heitz 2018) and its Smith weight, for the Monte
Carlo estimates computed on the CPU. alpha = roughness^2, as in Blender's Principled BSDF."""
import math

import numpy as np

# The GGX alpha floor: a mirror is a lobe this narrow (a narrower one's peak no longer fits a
# float32 D and its edges no longer resolve in a half-vector's cosine).
MIN_ALPHA = 1e-3
# The floor of the lobe the lamp split integrates lamps against (lamp_split.glsl). A lobe's tail
# grows as alpha squared, and a lamp is bright: at MIN_ALPHA a mirror's tail reads 0.002-0.005
# of a sun's light 16 degrees from its highlight (mirror_floor), which neither EEVEE nor Cycles
# shows (both take roughness 0 for a perfect mirror). Its samples are drawn from the lobe itself,
# so value and pdf agree where a half-vector's cosine rounds to 1.
LAMP_MIN_ALPHA = 1e-4


def ggx_alpha(roughness):
    """The GGX alpha of ROUGHNESS (a number or an array), at least MIN_ALPHA."""
    return np.maximum(np.asarray(roughness, np.float64) ** 2, MIN_ALPHA)


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
