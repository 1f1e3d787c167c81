"""The frame sequence over the frames a user renders: every quad pixel originates rays, each
pixel's samples spread evenly over time, history ping-pongs between two distinct textures,
and the history is read where analytic geometry says the reflection was last frame.

Observed from the chain's outputs (ray directions, the temporal pass's own record of
where it read), never by re-deriving the shader's index arithmetic.
"""
import numpy as np
import pytest

from gpu_harness import run_synthetic_chain
from oracles import ggx_normal_cdf
from synthetic import corridor, facing_plane, mirror_image, perspective, pixel_rays, raycast
from ssr_addon.core.frame_sequence import STRIDE, FrameSequence
from ssr_addon.core.settings import ChainSettings


def animation_state():
    from ssr_addon.core.chain import ChainState
    return ChainState()


def test_quad_pixels_all_originate_rays_within_four_frames(gpu_backend):
    """Each pixel of a 2x2 quad has its own tilted normal, so a mirror ray's direction names
    the pixel it left from; over any 4 consecutive frames all four must appear in every quad."""
    size = 16
    depth, _, projection = facing_plane(size, size)
    tilt = np.array([[(-0.2, -0.2), (0.2, -0.2)], [(-0.2, 0.2), (0.2, 0.2)]])  # [row][column] in image order
    normal = np.ones((size, size, 3), np.float32)
    normal[..., :2] = np.tile(tilt, (size // 2, size // 2, 1))
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    settings = ChainSettings(use_importance_sampling=False, half_resolution=True, max_roughness=1.0,
                             resolve_samples=1, camera_facing_fade=0.0)
    state = animation_state()
    origins = []
    for frame in range(7):
        arrays, _ = run_synthetic_chain(depth, normal, np.zeros_like(depth), projection, settings, state=state)
        if frame == 0:
            continue  # a first frame runs several iterations; the outputs show its last
        direction = arrays["ray_dir"][..., :3]  # one per quad, image order
        # Mirror of (0, 0, -1) about n: its x, y have the signs of n's tilt.
        column = (direction[..., 0] > 0).astype(int)
        row = (direction[..., 1] > 0).astype(int)
        origins.append(row * 2 + column)
    origins = np.array(origins)
    for first in range(len(origins) - 3):
        window = np.sort(origins[first:first + 4], axis=0)
        assert (window == np.arange(4)[:, None, None]).all(), f"frames {first}..{first + 3} miss a quad pixel"


def lobe_points(arrays, alpha):
    """The 2D point each ray was drawn from: seen head on, the GGX visible-normal sampler maps
    u1 to the CDF of D(h) cos in theta_h and u2 to the azimuth (Heitz 2018)."""
    direction = arrays["ray_dir"][..., :3]
    h = direction + np.array([0.0, 0.0, 1.0])
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    return np.stack([ggx_normal_cdf(h[..., 2], alpha), (np.arctan2(h[..., 1], h[..., 0]) / (2 * np.pi)) % 1.0], -1)


def discrepancy(points):
    """Kolmogorov-Smirnov distance of each pixel's 1D points from uniform: (..., n) -> (...)."""
    ordered = np.sort(points, axis=-1)
    n = points.shape[-1]
    upper = np.arange(1, n + 1) / n - ordered
    lower = ordered - np.arange(n) / n
    return np.maximum(upper.max(-1), lower.max(-1))


@pytest.mark.parametrize("half_resolution", [False, True])
def test_each_pixels_samples_spread_evenly_over_frames(gpu_backend, half_resolution):
    """16 rays of one pixel: independent uniform points would sit about 0.21 from uniform (KS).
    On the base-2 axis 16 consecutive strides hold one point in each 1/16 interval, which a
    per-pixel rotation shifts: at most 2/16 from uniform; the base-3 axis fills each 1/9
    interval at least once: at most 3/16. The frozen sequence this replaced kept every pixel
    in one 1/256 interval (KS near 1)."""
    size, roughness, rays = 8, 0.5, 16
    depth, normal, projection = facing_plane(size, size)
    settings = ChainSettings(max_roughness=1.0, resolve_samples=1, half_resolution=half_resolution)
    state = animation_state()
    frames_per_ray = 4 if half_resolution else 1
    points = {}
    run_synthetic_chain(depth, normal, np.full_like(depth, roughness), projection, settings, state=state)
    for frame in range(1, rays * frames_per_ray + 1):  # after the first frame, one iteration each
        arrays, _ = run_synthetic_chain(depth, normal, np.full_like(depth, roughness), projection, settings,
                                        state=state)
        # In half resolution a texel's rays come from its four quad pixels in turn (the test
        # above), each with its own sequence: group them by frame modulo 4.
        origin = frame % 4 if half_resolution else None
        points.setdefault(origin, []).append(lobe_points(arrays, roughness ** 2))
    for origin, per_frame in points.items():
        samples = np.stack(per_frame, -1)  # (rows, columns, 2, rays of this origin)
        assert samples.shape[-1] == rays
        base2, base3 = discrepancy(samples[..., 0, :]), discrepancy(samples[..., 1, :])
        print(f"origin {origin}: KS u1 max {base2.max():.3f}, u2 max {base3.max():.3f}")
        assert base2.max() <= 2.0 / rays, f"u1 discrepancy up to {base2.max():.3f}"
        assert base3.max() <= 3.0 / rays, f"u2 discrepancy up to {base3.max():.3f}"


def test_sample_indices_of_consecutive_frames_fill_every_stratum():
    """The policy itself: any 16 consecutive frames cover every residue modulo 16 and 9."""
    for first in (-5, 0, 1, 1000):
        sequence = FrameSequence()
        indices = []
        for frame in range(first, first + 16):
            sequence.start_frame(frame)
            indices.append(sequence.next_iteration().sample_index)
        assert len({index % 16 for index in indices}) == 16
        assert len({index % 9 for index in indices}) == 9
    assert STRIDE % 2 == 1 and STRIDE % 3 != 0


def test_history_is_read_and_written_in_different_textures_every_frame(gpu_backend, monkeypatch):
    """Over a 6-frame run the temporal pass never samples the texture it draws into, and each
    frame reads exactly what the previous frame wrote."""
    from ssr_addon.core import gpu_backend as backend
    draws = []
    original = backend.FullscreenPass.draw

    def record(self, targets, samplers=(), **kwargs):
        if self.name == "temporal":
            draws.append((dict(samplers)["history_tx"], targets[0]))
        return original(self, targets, samplers, **kwargs)
    monkeypatch.setattr(backend.FullscreenPass, "draw", record)
    depth, normal, projection = corridor(32, 20)
    state = animation_state()
    for _ in range(6):
        run_synthetic_chain(depth, normal, np.full_like(depth, 0.2), projection, ChainSettings(), state=state)
    assert len(draws) >= 6
    for index, (read, written) in enumerate(draws):
        assert read is not written, f"temporal draw {index} samples its own target"
        if index > 0:
            assert read is draws[index - 1][1], f"temporal draw {index} does not read the last result"


def test_drawing_into_a_sampled_texture_is_refused(gpu_backend):
    from ssr_addon.core.gpu_backend import empty_texture
    from ssr_addon.core.gpu_passes import COPY
    texture = empty_texture((4, 4))
    with pytest.raises(AssertionError, match="samples"):
        COPY.draw([texture], samplers=(("source_tx", texture),))


def project_px(points, projection, size):
    """Screen position in pixels, y up (OpenGL order, as the Vector pass), of view-space points."""
    clip = np.einsum("ij,...j->...i", projection, np.concatenate([points, np.ones_like(points[..., :1])], -1))
    return (clip[..., :2] / clip[..., 3:] * 0.5 + 0.5) * size


def camera_motion(depth, projection, pan):
    """The Vector pass of a static scene after the camera moved by PAN along x: for each pixel,
    where its surface point was on screen last frame, less where it is now (pixels, y up)."""
    height, width = depth.shape
    points = pixel_rays(width, height, projection) * depth[..., None] + np.array([pan, 0.0, 0.0])
    v, u = np.mgrid[0:height, 0:width]
    now = np.stack([u + 0.5, height - (v + 0.5)], -1)
    motion = project_px(points, projection, (width, height)) - now
    return np.concatenate([motion, np.zeros_like(motion)], -1).astype(np.float32)


def test_hit_point_reprojection_matches_the_analytic_mirror_image(gpu_backend):
    """Camera pans along x over a mirror floor facing a wall (both invariant under the pan, so
    one G-buffer serves both frames). The history of a floor pixel must be read where the
    previous camera saw the mirror image of the wall point its reflected ray hits."""
    width, height, pan = 64, 40, 0.3
    projection = perspective(width, height)
    wall_only = [((-30.0, -1.0, -9.0), (30.0, 30.0, -8.0))]
    depth, normal = raycast(width, height, projection, wall_only, floor_y=-1.0)
    radiance = np.ones((height, width, 4), np.float32)
    settings = ChainSettings(half_resolution=False, resolve_samples=1, use_importance_sampling=False,
                             border_fade=0.0, camera_facing_fade=0.0)
    state = animation_state()
    run_synthetic_chain(depth, normal, np.zeros_like(depth), projection, settings, radiance, state=state)
    panned = np.eye(4, dtype=np.float32)
    panned[0, 3] = -pan  # camera moved by +pan along x
    arrays, _ = run_synthetic_chain(depth, normal, np.zeros_like(depth), projection, settings, radiance,
                                    state=state, view_matrix=panned, motion=camera_motion(depth, projection, pan))
    read_px = arrays["history_record"][..., 1:3]

    # Analytic: from the camera at (pan, 0, 0), the pixel's ray meets the floor y = -1, reflects,
    # meets the wall z = -8; the wall point's mirror image in the floor, seen by the camera at
    # the origin, is where the reflection was.
    rays = pixel_rays(width, height, projection)
    camera = np.array([pan, 0.0, 0.0])
    t_floor = -1.0 / rays[..., 1]
    floor_point = camera + t_floor[..., None] * rays
    reflected = mirror_image(rays, axis=1)
    t_wall = (-8.0 - floor_point[..., 2]) / reflected[..., 2]
    wall_point = floor_point + t_wall[..., None] * reflected
    image = mirror_image(wall_point, axis=1, plane=-1.0)
    expected_px = project_px(image, projection, (width, height))
    expected_px[..., 1] = height - expected_px[..., 1]  # image order, as read_px
    read_px = read_px.copy()
    read_px[..., 1] = height - read_px[..., 1]

    floor = (normal[..., 1] > 0.5) & (arrays["reflection"][..., 3] > 0.5) & (arrays["history_record"][..., 0] > 1)
    inside = (expected_px > 1).all(-1) & (expected_px < (width - 1, height - 1)).all(-1)
    checked = floor & inside
    assert checked.sum() > 200
    error = np.linalg.norm(read_px[checked] - expected_px[checked], axis=-1)
    assert np.percentile(error, 99) < 0.5, f"history read up to {error.max():.2f} px from the mirror image"


def test_mirror_only_cutoff_and_non_finite_radiance_stay_finite(gpu_backend):
    """max_roughness=0 traces mirrors only (its fade has no width), and a NaN/Inf patch in the
    lit scene never reaches the history: every output of a 4-frame run is finite."""
    depth, normal, projection = corridor(48, 32)
    roughness = np.where(np.arange(48)[None, :] < 24, 0.0, 0.3).astype(np.float32) + np.zeros_like(depth)
    radiance = np.ones((32, 48, 4), np.float32)
    radiance[2:8, 10:20] = np.nan
    radiance[2:8, 30:40] = np.inf
    state = animation_state()
    for _ in range(4):
        arrays, _ = run_synthetic_chain(depth, normal, roughness, projection, ChainSettings(max_roughness=0.0),
                                        radiance, state=state)
    for name in ("reflection", "history_record"):
        assert np.isfinite(arrays[name]).all(), name
    confidence = arrays["reflection"][..., 3]
    assert (confidence[roughness > 0] == 0).all()
    assert (confidence[(roughness == 0) & (normal[..., 1] > 0.5)] > 0).sum() > 50, "mirrors keep SSR"


MIRROR_FLOOR_SIZE = (64, 40)


def mirror_floor_reflection_change(state, radiance_then, radiance_now):
    """Four frames of STATE over a mirror floor before a wall, lit by RADIANCE_THEN ((H, W, 4) at
    MIRROR_FLOOR_SIZE), then one lit by RADIANCE_NOW, nothing moving: the last frame's reflection over
    the one before it, (N, 3) on the floor pixels SSR fully resolves in both."""
    width, height = MIRROR_FLOOR_SIZE
    projection = perspective(width, height)
    depth, normal = raycast(width, height, projection, [((-30.0, -1.0, -9.0), (30.0, 30.0, -8.0))], floor_y=-1.0)
    settings = ChainSettings(border_fade=0.0, camera_facing_fade=0.0)
    for _ in range(4):
        before, _ = run_synthetic_chain(depth, normal, np.zeros_like(depth), projection, settings, radiance_then,
                                        state=state)
    after, _ = run_synthetic_chain(depth, normal, np.zeros_like(depth), projection, settings, radiance_now, state=state)
    floor = (normal[..., 1] > 0.5) & (before["reflection"][..., 3] > 0.99) & (after["reflection"][..., 3] > 0.99)
    assert floor.sum() > 300
    return after["reflection"][floor][:, :3] / before["reflection"][floor][:, :3]


def test_light_that_changes_under_a_still_camera_shows_at_once(gpu_backend):
    """Nothing moves, but the lit scene doubles in brightness at frame 4 (an animated lamp):
    the Vector pass shows nothing, yet the reflection must show the new light in that very
    frame, not average it into the history a still shot keeps for ever. Mirror floor, so the
    reflection is exactly the radiance it hits, without noise."""
    width, height = MIRROR_FLOOR_SIZE
    lit = np.ones((height, width, 4), np.float32)
    ratio = mirror_floor_reflection_change(animation_state(), lit, 2 * lit)
    print(f"reflection after the light doubled: {np.median(ratio):.3f} x, lowest {ratio.min():.3f} x")
    assert np.abs(ratio - 2.0).max() <= 0.02, "the reflection lags behind the light"


def test_a_view_the_camera_held_keeps_its_history_through_a_noisier_capture(gpu_backend):
    """The live view follows a camera over a still scene (NavigatedViews), each moving view captured
    at one sample after a held view captured at many: where the camera did not move, the light at a
    pixel's hit differs from the history's by that one sample's noise, not by a change of the scene.
    The history is right there, so the view keeps it and shows the converged reflection, where an
    animation, whose lamps may have changed, restarts from the noisy capture. Mirror floor, so the
    reflection is the radiance it hits."""
    from ssr_addon.core.chain import ChainState
    width, height = MIRROR_FLOOR_SIZE
    lit = np.ones((height, width, 4), np.float32)
    noisy = lit.copy()
    noisy[..., :3] *= 1.0 + 0.3 * np.random.default_rng(7).choice([-1.0, 1.0], (height, width, 1))
    deviations = {name: float(np.abs(mirror_floor_reflection_change(state, lit, noisy) - 1.0).mean())
                  for name, state in (("navigated", ChainState(scene_holds_still=True)),
                                      ("animation", animation_state()))}
    print(f"mean change of the reflection through the noisy capture: {deviations}")
    # The noisy capture is one sample among the history's many: a tenth of its noise at most.
    assert deviations["navigated"] <= 0.03 < deviations["animation"], deviations
