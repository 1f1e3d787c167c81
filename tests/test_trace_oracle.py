"""The GLSL tracers agree with their numpy oracles, hit for hit, on analytic depth buffers."""
import numpy as np
import pytest

from gpu_harness import CLIP_END, CLIP_START, run_synthetic_chain
from oracles import march_linear, march_pixel_walk, reduction_pyramid, trace_mirror_rays
from synthetic import corridor, mirror_image, perspective, pixel_rays, raycast
from ssr_addon.core.settings import ChainSettings

# Mirror rays, one per pixel, no temporal accumulation: the tracer alone decides the hits.
MIRROR = dict(use_importance_sampling=False, half_resolution=False, use_temporal=False,
              resolve_samples=1, hiz_max_iterations=1024)


def traced(settings, scene=None, roughness=None):
    depth, normal, projection = scene or corridor()
    roughness = np.zeros_like(depth) if roughness is None else roughness
    arrays, _ = run_synthetic_chain(depth, normal, roughness, projection, settings)
    hits = np.concatenate([arrays["ray_hit"][..., :2], arrays["ray_dir"][..., 3:4],
                           arrays["ray_hit"][..., 3:4]], -1)  # (uv, distance, confidence) as the oracle
    return hits, arrays


def assert_hits_agree(gpu, cpu, shape):
    gpu_hit, cpu_hit = gpu[..., 3] > 0, cpu[..., 3] > 0
    assert cpu_hit.sum() > 0.1 * gpu_hit.size, "the synthetic scene should reflect a lot"
    agreement = (gpu_hit == cpu_hit).mean()
    assert agreement >= 0.995, f"hit masks differ on {(1 - agreement) * 100:.2f}% of pixels"
    both = gpu_hit & cpu_hit
    uv_error_px = np.abs(gpu[both, :2] - cpu[both, :2]) * np.array(shape[::-1])
    assert np.percentile(uv_error_px, 99) < 0.5
    # Rays grazing a pixel corner may resolve a tie differently in float32: allow 1 in 100.
    same_surface = np.isclose(gpu[both, 2], cpu[both, 2], rtol=1e-2, atol=1e-2)
    assert same_surface.mean() >= 0.99
    np.testing.assert_allclose(gpu[both, 3][same_surface], cpu[both, 3][same_surface], atol=1e-3)


def test_linear_trace_matches_numpy_oracle(gpu_backend):
    settings = ChainSettings(use_hiz=False, trace_steps=64, trace_stride=1.0, thickness=0.5, **MIRROR)
    depth, normal, projection = scene = corridor()
    gpu, _ = traced(settings, scene)
    cpu = trace_mirror_rays(depth, normal, np.zeros_like(depth), projection, CLIP_START, CLIP_END,
                            settings, march_linear)
    assert_hits_agree(gpu, cpu, depth.shape)


def test_hiz_trace_finds_every_hit_of_a_pixel_by_pixel_walk(gpu_backend):
    settings = ChainSettings(use_hiz=True, thickness=0.5, **MIRROR)
    depth, normal, projection = scene = corridor(pole_width=0.04)
    gpu, arrays = traced(settings, scene)
    assert ((arrays["ray_stats"][..., 0] == 2) | (depth >= CLIP_END)).all(), "every ray is expensive"
    assert arrays["ray_stats"][..., 2].max() >= 3, "rays should climb the pyramid"
    cpu = trace_mirror_rays(depth, normal, np.zeros_like(depth), projection, CLIP_START, CLIP_END,
                            settings, march_pixel_walk)
    assert_hits_agree(gpu, cpu, depth.shape)


def test_hiz_sees_one_pixel_thin_geometry_a_coarse_march_steps_over(gpu_backend):
    depth, normal, projection = scene = corridor(pole_width=0.04)
    pole_front = (normal[..., 2] > 0.99) & (depth > 3.9) & (depth < 4.0)
    pole_columns = np.nonzero(pole_front.any(axis=0))[0]
    assert len(pole_columns) == 1, "the pole should be one pixel wide"
    # Floor pixels right below the pole reflect it; find their hits on the pole column.
    def pole_hits(hits):
        columns = np.floor(hits[..., 0] * depth.shape[1]).astype(int)
        return ((hits[..., 3] > 0) & (columns == pole_columns[0]) & (hits[..., 2] < 3.5)).sum()
    hiz, _ = traced(ChainSettings(use_hiz=True, thickness=0.5, **MIRROR), scene)
    coarse, _ = traced(ChainSettings(use_hiz=False, trace_stride=6.0, thickness=0.5, **MIRROR), scene)
    assert pole_hits(hiz) > 3
    assert pole_hits(coarse) < pole_hits(hiz)


@pytest.mark.parametrize("reduction", ["hiz_downsample", "color_downsample"])
def test_pyramids_match_numpy_reductions(gpu_backend, reduction):
    """The Hi-Z pyramid is the min of the texels each cell covers, the colour pyramid their
    mean, level by level to 1x1, each level where its rectangle says in one atlas."""
    from ssr_addon.core import gpu_passes
    from ssr_addon.core.gpu_backend import TexturePool, download, upload
    from ssr_addon.core.pyramids import build_pyramid
    channels = 1 if reduction == "hiz_downsample" else 4
    image = np.random.default_rng(1).uniform(1, 50, (37, 61, channels)).astype(np.float32)  # odd sizes on purpose
    atlas, rects = build_pyramid(upload(image), getattr(gpu_passes, reduction.upper()), gpu_passes.PYRAMID_PACK,
                                 TexturePool())
    atlas_gl = download(atlas, channels)[::-1]
    expected = reduction_pyramid(image[::-1], np.nanmin if channels == 1 else np.nanmean)
    assert len(rects) == len(expected)
    for (x, y, width, height), level in zip(rects, expected):
        np.testing.assert_allclose(atlas_gl[y:y + height, x:x + width], level, rtol=1e-6)


def test_mirror_floor_hits_land_on_the_mirror_image(gpu_backend):
    """Floor pixels reflect the scene at the analytic mirror position, with either tracer."""
    depth, normal, projection = scene = corridor()
    rays = pixel_rays(depth.shape[1], depth.shape[0], projection)
    for use_hiz in (False, True):
        hits, _ = traced(ChainSettings(use_hiz=use_hiz, trace_steps=128, trace_stride=1.0, thickness=0.5,
                                       border_fade=0.0, camera_facing_fade=0.0, **MIRROR), scene)
        floor = (hits[..., 3] > 0) & np.all(np.isclose(normal, (0, 1, 0)), axis=-1)
        assert floor.sum() > 200
        position = rays[floor] * depth[floor][:, None]
        direction = mirror_image(position / np.linalg.norm(position, axis=-1, keepdims=True), axis=1)
        hit = position + direction * hits[floor][:, 2:3]
        clip = np.c_[hit, np.ones(len(hit))] @ projection.T
        uv = clip[:, :2] / clip[:, 3:4] * 0.5 + 0.5
        assert np.abs(uv - hits[floor][:, :2]).max() < 1.0 / depth.shape[0]


def test_background_and_rough_pixels_trace_nothing(gpu_backend):
    depth, _, _ = scene = corridor()
    rough_half = np.where(np.arange(depth.shape[1]) < depth.shape[1] // 2, 0.9, 0.0)
    roughness = np.repeat(rough_half[None], depth.shape[0], 0).astype(np.float32)
    hits, arrays = traced(ChainSettings(max_roughness=0.5, **MIRROR), scene, roughness)
    assert not (hits[..., 3] > 0)[:, : depth.shape[1] // 2].any()
    assert not (arrays["ray_hit"][..., 2] > 0)[depth >= CLIP_END].any(), "no ray from the sky"
    assert (hits[..., 3] > 0)[:, depth.shape[1] // 2:].any()


def test_edge_fading_dims_hits_only_where_their_rays_leave_the_screen(gpu_backend):
    """Edge fading ("Edge Fading" slide) hides the line where rays leave the screen. Over a
    mirror floor seen level, every reflected ray runs straight up the screen: hits near the
    top edge, where the rays leave, fade out; hits near the side edges keep their full
    weight, as their rays leave through the top (a fade by the distance to any edge dimmed
    the outer 8 % of the reflection on both sides)."""
    width, height = 80, 48
    projection = perspective(width, height)
    far_wall = [((-100.0, -1.0, -61.0), (100.0, 100.0, -60.0))]  # far enough for rays to climb near the top
    depth, normal = raycast(width, height, projection, far_wall, floor_y=-1.0)
    settings = ChainSettings(border_fade=0.08, camera_facing_fade=0.0, trace_steps=128, trace_stride=1.0,
                             thickness=2.0, max_distance=200.0, **MIRROR)
    hits, _ = traced(settings, (depth, normal, projection))
    hit = (hits[..., 3] > 0) & (normal[..., 1] > 0.5)  # the floor's reflections
    u, v, confidence = hits[..., 0], hits[..., 1], hits[..., 3]
    near_side = hit & ((u < 0.08) | (u > 0.92)) & (v < 0.9)
    near_top = hit & (v > 0.94)
    assert near_side.sum() >= 20 and near_top.sum() >= 20
    assert confidence[near_side].min() > 0.99
    np.testing.assert_allclose(confidence[near_top], (1 - v[near_top]) / 0.08, atol=0.02)
