"""resolve_resolution=half, the "Sparse Ray Tracing" slide's comparison: each traced ray's pixel
resolves its colour at the traced size and the result is scaled up bilinearly.

Checked against the full-resolution chain, not a port of the shader: with mirror rays and one
resolve sample, a half-resolution texel holds exactly the full-resolution reflection of the pixel
its ray started from, so a still that visits all four pixels of every quad is the bilinear
upscale of each quad's mean of the full-resolution reflection."""
import numpy as np

from gpu_harness import run_synthetic_chain
from synthetic import corridor
from ssr_addon.core.settings import ChainSettings

# Mirror rays, one resolve sample, no spatial filter: a pixel's reflection is its own ray's hit.
# 8 iterations: every pixel of each 2x2 quad starts a ray twice, averaged by the still.
STILL = dict(use_importance_sampling=False, resolve_samples=1, use_spatial_filter=False,
             accumulate_iterations=8, noise_threshold=0.0, hiz_max_iterations=1024)


def textured_radiance(shape):
    """A scene colour with detail at every pixel, so a misplaced texel shows."""
    rows, columns = np.indices(shape)
    pattern = np.stack([(rows // 3 + columns // 5) % 2, (rows * 7 + columns * 3) % 11 / 10.0,
                        np.full(shape, 0.5)], -1)
    return np.concatenate([pattern, np.ones((*shape, 1))], -1).astype(np.float32)


def bilinear_upscale(image, shape):
    """IMAGE (half size) sampled at each full-resolution pixel centre, edges clamped (a GPU sampler)."""
    def axis(full, half):
        position = (np.arange(full) + 0.5) / 2.0 - 0.5
        low = np.floor(position).astype(int)
        return np.clip(low, 0, half - 1), np.clip(low + 1, 0, half - 1), (position - low)
    (y0, y1, fy), (x0, x1, fx) = axis(shape[0], image.shape[0]), axis(shape[1], image.shape[1])
    fy, fx = fy[:, None, None], fx[None, :, None]
    top = image[y0][:, x0] * (1 - fx) + image[y0][:, x1] * fx
    bottom = image[y1][:, x0] * (1 - fx) + image[y1][:, x1] * fx
    return top * (1 - fy) + bottom * fy


def test_half_resolution_resolve_is_the_upscaled_quad_mean_of_the_full_resolve(gpu_backend):
    depth, normal, projection = corridor()
    roughness = np.zeros_like(depth)
    radiance = textured_radiance(depth.shape)
    full, _ = run_synthetic_chain(depth, normal, roughness, projection,
                                  ChainSettings(half_resolution=False, **STILL), radiance=radiance)
    half, _ = run_synthetic_chain(depth, normal, roughness, projection,
                                  ChainSettings(half_resolution=True, resolve_resolution="half", **STILL),
                                  radiance=radiance)
    reflection = full["reflection"]
    assert (reflection[..., 3] > 0.5).mean() > 0.1, "the corridor's floor should reflect the walls"
    height, width = depth.shape
    quad_mean = reflection.reshape(height // 2, 2, width // 2, 2, 4).mean(axis=(1, 3))
    expected = bilinear_upscale(quad_mean, depth.shape)
    error = np.abs(half["reflection"] - expected)
    assert np.percentile(error, 99) < 0.02 and error.mean() < 0.002, \
        f"half-resolution resolve differs from the upscaled quad mean: mean {error.mean():.4f}, max {error.max():.3f}"
    # and it is a different image from the full-resolution resolve: blurred where the reflection has detail
    assert np.abs(half["reflection"] - reflection).mean() > 10 * error.mean()


def test_full_resolution_resolve_is_unchanged_by_the_setting_without_half_resolution_rays(gpu_backend):
    depth, normal, projection = corridor()
    radiance = textured_radiance(depth.shape)
    images = [run_synthetic_chain(depth, normal, np.zeros_like(depth), projection,
                                  ChainSettings(half_resolution=False, resolve_resolution=where, **STILL),
                                  radiance=radiance)[0]["reflection"] for where in ("full", "half")]
    np.testing.assert_array_equal(images[0], images[1])
