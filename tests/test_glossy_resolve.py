"""A settled glossy still equals the lobe integral of exact rays, not a blur of it.

The expected reflection is a CPU Monte Carlo estimate computed another way than the
chain: visible GGX normals drawn in numpy, each ray intersected with the boxes exactly
(synthetic.intersect_boxes), a hit counting where the camera also sees it (a screen-space
reflection can show nothing else), weighted by the Smith masking of its direction.

The resolve's cones and the spatial filter trade blur for noise. Both stand for the few
rays of one iteration; a still averages many, so left at one iteration's width they blur
the settled image past the lobe.
"""
import numpy as np
import pytest

from gpu_harness import run_synthetic_chain
from synthetic import camera_texel, intersect_boxes, seen_by_camera
from test_clean_stills import BOXES, COLOURS, HEIGHT, WIDTH, mirror_scene
from ssr_addon.core.ggx import ggx_alpha, sample_visible_normals, stratified_points, visible_normal_weight
from ssr_addon.core.settings import preset

pytestmark = pytest.mark.slow  # a Monte Carlo estimate of every glossy pixel

ROUGHNESS = 0.25
SAMPLES_PER_PIXEL = 256
STRIDE = 3  # the estimate is made at every third pixel in each direction
# Pixels nearer the screen's border than this are not judged: the chain fades hits there.
BORDER_PX = 12


def exact_reflection(projection, depth, rays, floor, roughness, colours=COLOURS, stride=STRIDE, boxes=BOXES,
                     image=None):
    """(H, W, 3) reflected radiance premultiplied by confidence of the floor pixels on a STRIDE
    grid (NaN elsewhere): the normalised GGX lobe integral of exact rays. A hit shows its box's
    colour, or with IMAGE (H, W, 3) the colour of the texel the camera sees it in."""
    rows, columns = np.nonzero(floor)
    keep = (rows % stride == 0) & (columns % stride == 0)
    rows, columns = rows[keep], columns[keep]
    points = rays[rows, columns] * depth[rows, columns, None]
    to_eye = -points / np.linalg.norm(points, axis=-1, keepdims=True)
    # The floor's frame: tangents x and -z, normal y (right-handed).
    frame = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]).T
    view_local = to_eye @ frame
    alpha = np.full((len(rows), 1), ggx_alpha(roughness))
    half = sample_visible_normals(view_local[:, None, :], alpha, stratified_points(SAMPLES_PER_PIXEL))
    light_local = 2 * np.sum(view_local[:, None, :] * half, -1, keepdims=True) * half - view_local[:, None, :]
    weight = visible_normal_weight(view_local[:, 2:3], light_local[..., 2], alpha ** 2)
    directions = light_local @ frame.T
    origins = np.broadcast_to(points[:, None, :], directions.shape)
    t, box, _ = intersect_boxes(origins, directions, boxes, np.full(weight.shape, 1e3))
    hits = origins + directions * t[..., None]
    seen = (box >= 0) & seen_by_camera(hits, projection, depth)
    if image is None:
        colour = colours[np.maximum(box, 0)]
    else:
        hit_row, hit_column, _ = camera_texel(hits, projection, depth.shape[::-1])
        colour = image[hit_row, hit_column]
    radiance = (weight[..., None] * np.where(seen[..., None], colour, 0.0)).sum(1)
    premultiplied = np.full(depth.shape + (3,), np.nan)
    premultiplied[rows, columns] = radiance / weight.sum(-1)[:, None]
    return premultiplied


def settled_error(settings, colours=COLOURS, roughness=ROUGHNESS, size=(WIDTH, HEIGHT)):
    """Mean absolute difference of the settled still's premultiplied reflection from the exact
    estimate on the judged floor pixels, and the estimate's mean there. Below 640x360 every pixel
    is estimated, and the unjudged border shrinks with the frame."""
    projection, depth, normal, rays, floor, radiance, surface_roughness = mirror_scene(roughness, colours, size)
    scale = size[0] / WIDTH
    expected = exact_reflection(projection, depth, rays, floor, roughness, colours, STRIDE if scale >= 1 else 1)
    border = max(round(BORDER_PX * scale), 1)
    judged = np.isfinite(expected[..., 0])
    judged[:border], judged[-border:], judged[:, :border], judged[:, -border:] = False, False, False, False
    arrays, _ = run_synthetic_chain(depth, normal, surface_roughness, projection, settings, radiance=radiance)
    reflection = arrays["reflection"][..., :3]
    return np.abs(reflection - expected)[judged].mean(), expected[judged].mean()


def test_filters_narrow_as_the_history_grows(gpu_backend):
    """A settled balanced still within 10 % (mean absolute error, relative to the mean) of the
    exact lobe integral, as the same chain is without its blur-for-noise filters. The
    last round's chain, its filters one iteration wide at every iteration, was 22 % off."""
    balanced = preset("balanced").with_overrides(["border_fade=0"])
    error, scale = settled_error(balanced)
    unfiltered, _ = settled_error(balanced.with_overrides(["use_cone_filter=false", "use_spatial_filter=false"]))
    assert unfiltered <= 0.1 * scale, f"the chain without filters is {unfiltered / scale:.1%} off the estimate"
    assert error <= 0.1 * scale, (
        f"settled balanced still {error / scale:.1%} off the exact lobe integral, {unfiltered / scale:.1%} "
        "without its cone and spatial filters: the filters blur a settled image")


def test_a_nearly_smooth_floor_settles_to_its_own_lobe_at_a_low_resolution(gpu_backend):
    """At 160x90 a traced texel turns a 0.15-rough floor's ray further than its lobe is wide.
    The ratio estimator normalises each iteration's weights, so rays reused from beside the lobe
    still weigh in full, and a still averaging such iterations settles on their blur of the
    reflection, unless the floor's own sharp rays (sharp_roughness 0.2 takes it) weigh in
    with them by the share of the lobe each covers (the balance heuristic over their pdfs).
    A still stops once a doubling of its iterations moves it by under noise_threshold, so it may
    lie that far from the lobe integral, and as far again from the pixel grid it reads the boxes
    from (a quarter of the floor's pixels border one); reuse alone was 5.3 % off, the chain taking
    its own ray only where the reused rays weighed less than one 4.3 %."""
    balanced = preset("balanced").with_overrides(["border_fade=0", "sharp_roughness=0.2"])
    error, scale = settled_error(balanced, roughness=0.15, size=(160, 90))
    assert error <= 2 * balanced.noise_threshold * scale, \
        f"settled balanced still {error / scale:.1%} off the exact lobe integral"


def test_a_glowing_box_keeps_its_reflection_when_settled(gpu_backend):
    """The firefly guard averages one iteration's rays tone-mapped, so that the few rays reaching a
    lamp-bright surface cannot dominate a pixel; at full strength on every iteration it dims that
    reflection for good, however many iterations the still averages (the wet street's lamps).
    With the nearest box glowing at 16 times its colour, the guard may add to a settled still's
    error against the exact lobe integral no more than the share a still is allowed to move when
    it is called converged (noise_threshold). At full strength it added 3.4 % of the level."""
    glowing = COLOURS * np.array([[1.0], [1.0], [16.0]], np.float32)
    balanced = preset("balanced").with_overrides(["border_fade=0"])
    error, scale = settled_error(balanced, glowing)
    unguarded, _ = settled_error(balanced.with_overrides(["use_firefly_guard=false"]), glowing)
    assert unguarded <= 0.1 * scale, f"the chain without its guard is {unguarded / scale:.1%} off the estimate"
    assert error - unguarded <= balanced.noise_threshold * scale, (
        f"settled balanced still {error / scale:.1%} off the exact lobe integral with a glowing box, "
        f"{unguarded / scale:.1%} without the firefly guard: the guard dims what the history has averaged")


def test_a_glossy_reflection_reaches_the_screen_edge_as_a_correct_one_does(gpu_backend):
    """A 0.15-rough floor under a far wall that rises past the frame's top: the floor's nearest
    rows mirror the wall just below the top edge, and part of each of their lobes lies above it.
    A correct screen-space reflection keeps the part that the camera sees, which already falls
    smoothly towards the edge over the lobe's own spread. Judged where the lobe loses at least
    7 % past the edge, against the exact lobe integral of what the camera sees, the settled still
    may be off by what a still may be (noise_threshold) and as far again from the pixel grid, as
    the low-resolution floor above. Fading each glossy ray as a mirror's took 4.9 % off."""
    size = (160, 90)
    wall = [((-100.0, -1.0, -31.0), (100.0, 100.0, -30.0))]
    colour = np.array([(0.8, 0.7, 0.5)], np.float32)
    projection, depth, normal, rays, floor, radiance, surface_roughness = mirror_scene(0.15, colour, size, wall)
    expected = exact_reflection(projection, depth, rays, floor, 0.15, colour, 1, wall)
    kept = expected[..., 0] / colour[0, 0]
    judged = np.isfinite(kept) & (kept < 0.93) & (kept > 0.0)
    assert judged.sum() >= 300, "the floor's nearest rows must lose part of their lobes past the top"
    balanced = preset("balanced")
    arrays, _ = run_synthetic_chain(depth, normal, surface_roughness, projection, balanced, radiance=radiance)
    error = np.abs(arrays["reflection"][..., :3] - expected)[judged].mean() / expected[judged].mean()
    assert error <= 2 * balanced.noise_threshold, f"{error:.1%} off the exact lobe integral by the top edge"


def test_a_mirror_keeps_the_contrast_of_what_it_reflects(gpu_backend):
    """A mirror at 160x90 under a wall striped one texel per row: each floor pixel's ray hits one
    texel, whose colour is what the mirror shows (the frame is already filtered over each pixel,
    and a plane mirror's virtual image is no nearer than what it mirrors, so nothing is
    magnified). A blend of the texels around each hit greys the stripes: it came out 12 % off
    the exact lobe integral. Allowed: what a still may be off (noise_threshold), twice, as above."""
    size = (160, 90)
    wall = [((-100.0, -1.0, -13.0), (100.0, 100.0, -12.0))]
    colours = np.array([(0.9, 0.8, 0.1)], np.float32)
    projection, depth, normal, rays, floor, radiance, surface_roughness = mirror_scene(0.0, colours, size, wall)
    stripes = np.where((np.arange(size[1]) % 2 == 0)[:, None, None], colours[0], np.float32(0.1))
    radiance[..., :3] = np.where(np.isclose(normal[..., 2], 1.0)[..., None], stripes, radiance[..., :3])
    expected = exact_reflection(projection, depth, rays, floor, 0.0, stride=1, boxes=wall, image=radiance[..., :3])
    judged = np.isfinite(expected[..., 0])
    judged[-2:], judged[:, :2], judged[:, -2:] = False, False, False  # the floor's own silhouette
    balanced = preset("balanced")
    arrays, _ = run_synthetic_chain(depth, normal, surface_roughness, projection, balanced, radiance=radiance)
    error = np.abs(arrays["reflection"][..., :3] - expected)[judged].mean() / expected[judged].mean()
    assert error <= 2 * balanced.noise_threshold, f"the mirror is {error:.1%} off the exact lobe integral"
