"""GGX importance sampling: sample histograms follow the analytic pdf, every ray keeps its pdf,
and at roughness 0 the stochastic chain reproduces the mirror result."""
import numpy as np
import pytest

from gpu_harness import run_synthetic_chain
from oracles import ggx_normal_cdf, view_positions, visible_normal_pdf
from synthetic import corridor, facing_plane
from ssr_addon.core.settings import ChainSettings
from ssr_addon.core.gpu_passes import LOBE_TAIL

ONE_RAY_PER_PIXEL = dict(half_resolution=False, use_temporal=False, resolve_samples=1)


def half_vectors(view, direction):
    h = view + direction
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


@pytest.mark.parametrize("roughness", [0.2, 0.5, 0.8])
def test_sample_histogram_matches_the_ggx_pdf(gpu_backend, roughness):
    depth, normal, projection = facing_plane()
    arrays, _ = run_synthetic_chain(depth, normal, np.full_like(depth, roughness), projection,
                                    ChainSettings(max_roughness=1.0, **ONE_RAY_PER_PIXEL))
    alpha = roughness ** 2
    view = np.array([0.0, 0.0, 1.0])
    h = half_vectors(view, arrays["ray_dir"][..., :3].reshape(-1, 3))
    # Seen head on, visible normals are distributed as D(h) cos(theta_h), whose CDF in
    # theta_h is tan^2 / (alpha^2 + tan^2): mapped through it the samples must be uniform,
    # on all but the outermost LOBE_TAIL, which is never drawn.
    uniform = np.sort(ggx_normal_cdf(h[:, 2], alpha))
    ks = np.abs(uniform - (np.arange(uniform.size) + 0.5) / uniform.size * (1.0 - LOBE_TAIL)).max()
    assert ks < 0.02, f"Kolmogorov-Smirnov distance {ks:.4f}"
    azimuth = np.sort((np.arctan2(h[:, 1], h[:, 0]) / (2 * np.pi)) % 1.0)
    assert np.abs(azimuth - (np.arange(azimuth.size) + 0.5) / azimuth.size).max() < 0.02
    # Each ray carries the pdf of its own direction.
    expected = visible_normal_pdf(1.0, h[:, 2], alpha) if alpha > 1e-3 else None
    np.testing.assert_allclose(arrays["ray_hit"][..., 2].ravel(), expected, rtol=2e-3)


def test_random_points_follow_the_ggx_pdf_too(gpu_backend):
    """ray_sampling=random (the slides' comparison) draws the same lobe, at independent points:
    the KS distance stays within its 99.9 % bound for a sample this size, 1.95 / sqrt(n)."""
    depth, normal, projection = facing_plane()
    arrays, _ = run_synthetic_chain(depth, normal, np.full_like(depth, 0.5), projection,
                                    ChainSettings(max_roughness=1.0, ray_sampling="random", **ONE_RAY_PER_PIXEL))
    h = half_vectors(np.array([0.0, 0.0, 1.0]), arrays["ray_dir"][..., :3].reshape(-1, 3))
    uniform = np.sort(ggx_normal_cdf(h[:, 2], 0.5 ** 2))
    ks = np.abs(uniform - (np.arange(uniform.size) + 0.5) / uniform.size * (1.0 - LOBE_TAIL)).max()
    assert ks < 1.95 / np.sqrt(uniform.size), f"Kolmogorov-Smirnov distance {ks:.4f}"


def test_uniform_directions_spread_evenly_over_the_hemisphere(gpu_backend):
    """ray_sampling=uniform: cos(theta) of the ray about the normal is uniform on
    [LOBE_TAIL, 1] (the grazing band is cut like the lobe's tail), azimuth uniform,
    and every ray carries that constant pdf, whatever the roughness."""
    depth, normal, projection = facing_plane()
    arrays, _ = run_synthetic_chain(depth, normal, np.full_like(depth, 0.2), projection,
                                    ChainSettings(max_roughness=1.0, ray_sampling="uniform", **ONE_RAY_PER_PIXEL))
    direction = arrays["ray_dir"][..., :3].reshape(-1, 3)
    cos_theta = np.sort(direction[:, 2])
    n = cos_theta.size
    ks = np.abs((cos_theta - LOBE_TAIL) / (1.0 - LOBE_TAIL) - (np.arange(n) + 0.5) / n).max()
    assert ks < 0.02, f"Kolmogorov-Smirnov distance {ks:.4f}"
    azimuth = np.sort((np.arctan2(direction[:, 1], direction[:, 0]) / (2 * np.pi)) % 1.0)
    assert np.abs(azimuth - (np.arange(n) + 0.5) / n).max() < 0.02
    np.testing.assert_allclose(arrays["ray_hit"][..., 2].ravel(), 1.0 / (2 * np.pi * (1.0 - LOBE_TAIL)), rtol=1e-5)


def test_rays_keep_their_pdf_at_oblique_views(gpu_backend):
    depth, normal, projection = corridor()
    roughness = np.full_like(depth, 0.35)
    arrays, _ = run_synthetic_chain(depth, normal, roughness, projection,
                                    ChainSettings(**ONE_RAY_PER_PIXEL))
    _, incident = view_positions(depth, np.linalg.inv(projection))
    traced = arrays["ray_hit"][..., 2] > 0
    view = -incident[traced]
    n = normal[traced]
    h = half_vectors(view, arrays["ray_dir"][traced][:, :3])
    expected = visible_normal_pdf(np.sum(n * view, -1), np.sum(n * h, -1), 0.35 ** 2)
    np.testing.assert_allclose(arrays["ray_hit"][traced][:, 2], expected, rtol=5e-3)


def smooth_radiance(depth):
    """A radiance buffer that varies smoothly across the screen, so a wrong hit shows."""
    height, width = depth.shape
    v, u = np.mgrid[0:height, 0:width]
    return np.stack([u / width, v / height, 0.5 + 0.5 * np.sin(u / 5.0), np.ones_like(u)], -1).astype(np.float32)


def test_roughness_zero_reproduces_the_mirror_result(gpu_backend):
    depth, normal, projection = corridor()
    roughness = np.zeros_like(depth)
    radiance = smooth_radiance(depth)
    mirror, _ = run_synthetic_chain(depth, normal, roughness, projection,
                                    ChainSettings(use_importance_sampling=False, use_cone_filter=False,
                                                  **ONE_RAY_PER_PIXEL), radiance)
    stochastic, _ = run_synthetic_chain(depth, normal, roughness, projection,
                                        ChainSettings(**ONE_RAY_PER_PIXEL), radiance)
    hit = mirror["reflection"][..., 3] > 0
    assert hit.mean() > 0.1
    # GGX at roughness 0 (alpha clamped to 1e-3) scatters rays by about a milliradian:
    # the same hits to a fraction of a pixel, and where both lie in one texel, which a sharp
    # hit reads, the same colour and confidence.
    stochastic_hit = stochastic["reflection"][..., 3] > 0
    assert (hit == stochastic_hit).mean() > 0.995
    both = hit & stochastic_hit
    size = np.array(depth.shape[::-1])
    uv_error_px = np.abs(stochastic["ray_hit"][both, :2] - mirror["ray_hit"][both, :2]) * size
    assert np.percentile(uv_error_px, 95) < 0.25
    same_texel = (np.floor(stochastic["ray_hit"][..., :2] * size) == np.floor(mirror["ray_hit"][..., :2] * size)).all(-1)
    assert (same_texel[both]).mean() > 0.5
    one_texel = both & same_texel
    close = np.isclose(stochastic["reflection"][one_texel], mirror["reflection"][one_texel], atol=0.02).all(-1)
    assert close.mean() > 0.99

    # Half-resolution tracing with four reused rays and temporal accumulation lands close by.
    sparse, _ = run_synthetic_chain(depth, normal, roughness, projection, ChainSettings(), radiance)
    both = hit & (sparse["reflection"][..., 3] > 0.5)
    assert both.sum() > 0.8 * hit.sum()
    radiance_error = np.abs(sparse["reflection"][both, :3] / sparse["reflection"][both, 3:]
                            - mirror["reflection"][both, :3] / mirror["reflection"][both, 3:])
    assert np.median(radiance_error) < 0.02
