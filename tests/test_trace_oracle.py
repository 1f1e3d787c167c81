"""The GLSL linear trace agrees with its numpy oracle, hit for hit, on an analytic depth buffer."""
import numpy as np

from oracles import trace_linear
from synthetic import corridor
from ssr_addon.params import ChainSettings

CLIP_START, CLIP_END = 0.1, 100.0


def gpu_trace(depth, normal, roughness, projection, settings):
    from ssr_addon.chain import ChainInputs, trace_hits, trace_params
    from ssr_addon.gpu_backend import download, upload
    inputs = ChainInputs(
        radiance_tx=None, depth_tx=upload(depth), normal_tx=upload(normal), roughness_tx=upload(roughness),
        combined_tx=None, specular_color_tx=None, specular_indirect_tx=None,
        view_matrix=np.eye(4, dtype=np.float32), projection_matrix=projection,
        clip_start=CLIP_START, clip_end=CLIP_END)
    return download(trace_hits(inputs, settings, trace_params(inputs, settings)))


def test_linear_trace_matches_numpy_oracle(gpu_backend):
    depth, normal, projection = corridor()
    roughness = np.zeros_like(depth)
    settings = ChainSettings(trace_steps=64, thickness=0.5)
    gpu = gpu_trace(depth, normal, roughness, projection, settings)
    cpu = trace_linear(depth, normal, roughness, projection, CLIP_START, CLIP_END, settings)

    gpu_hit, cpu_hit = gpu[..., 3] > 0, cpu[..., 3] > 0
    assert cpu_hit.sum() > 0.1 * depth.size, "the synthetic scene should reflect a lot"
    agreement = (gpu_hit == cpu_hit).mean()
    assert agreement >= 0.995, f"hit masks differ on {(1 - agreement) * 100:.2f}% of pixels"
    both = gpu_hit & cpu_hit
    uv_error_px = np.abs(gpu[both, :2] - cpu[both, :2]) * np.array(depth.shape[::-1])
    assert np.percentile(uv_error_px, 99) < 0.5
    np.testing.assert_allclose(gpu[both, 2], cpu[both, 2], rtol=1e-2, atol=1e-2)
    np.testing.assert_allclose(gpu[both, 3], cpu[both, 3], atol=1e-3)


def test_mirror_floor_hits_land_on_the_mirror_image(gpu_backend):
    """Floor pixels below the back wall reflect the wall at the mirrored height (analytic)."""
    depth, normal, projection = corridor()
    settings = ChainSettings(trace_steps=128, thickness=0.5, border_fade=0.0, camera_facing_fade=0.0)
    hits = gpu_trace(depth, normal, np.zeros_like(depth), projection, settings)
    height, width = depth.shape
    from synthetic import pixel_rays
    rays = pixel_rays(width, height, projection)
    checked = 0
    for row in range(height):
        for col in range(width):
            if hits[row, col, 3] <= 0 or not np.allclose(normal[row, col], (0, 1, 0)):
                continue
            # Mirror of the floor point's camera ray in y = -1: the camera's image at y = -2.
            position = rays[row, col] * depth[row, col]
            direction = position / np.linalg.norm(position)
            direction[1] = -direction[1]
            distance = hits[row, col, 2]
            hit = position + direction * distance
            clip = projection @ np.append(hit, 1.0)
            uv = clip[:2] / clip[3] * 0.5 + 0.5
            assert np.allclose(uv, hits[row, col, :2], atol=1.0 / height), (row, col)
            checked += 1
    assert checked > 200


def test_background_and_rough_pixels_trace_nothing(gpu_backend):
    depth, normal, projection = corridor()
    roughness = np.where(np.arange(depth.shape[1]) < depth.shape[1] // 2, 0.9, 0.0)[None].repeat(depth.shape[0], 0)
    hits = gpu_trace(depth, normal, roughness.astype(np.float32), projection, ChainSettings(max_roughness=0.5))
    assert not (hits[..., 3] > 0)[:, : depth.shape[1] // 2].any()
    assert not (hits[..., 3] > 0)[depth >= CLIP_END].any()
    assert (hits[..., 3] > 0)[:, depth.shape[1] // 2:].any()
