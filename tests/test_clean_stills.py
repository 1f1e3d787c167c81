"""Clean stills: a balanced still of a mirror floor shows the analytic mirror image, with no
speckle and no stair-steps, away from the edges a pixel grid must soften anyway.

The expected image comes from geometry, not from the shader: each floor pixel's camera
ray is reflected about the floor and intersected with the boxes in numpy; where the
camera also sees the point it hits, SSR must show that box's colour.
"""
import numpy as np
from scipy.ndimage import maximum_filter, minimum_filter

from gpu_harness import CLIP_END, run_synthetic_chain
from synthetic import intersect_boxes, mirror_image, perspective, pixel_rays, raycast, seen_by_camera
from ssr_addon.core.ray_budget import ray_budget
from ssr_addon.core.settings import preset

WIDTH, HEIGHT = 640, 360
FLOOR_Y = -1.0
# A back wall and two boxes on the floor, each its own colour (radiance); their top edges run
# away from the camera, so their reflections are slanted lines where stair-steps would show.
BOXES = [((-4.0, -1.0, -12.0), (4.0, 3.0, -11.0)),
         ((-2.2, -1.0, -7.0), (-0.6, 0.4, -4.5)),
         ((0.7, -1.0, -6.5), (1.9, -0.2, -3.5))]
COLOURS = np.array([(0.15, 0.2, 0.7), (0.9, 0.8, 0.1), (0.8, 0.15, 0.1)], np.float32)
MARGIN_PX = 2  # pixels within this distance of an edge of the mirror image are not judged
TOLERANCE = 0.05  # per channel, against box contrasts of 0.5 and more


def mirror_scene(roughness, colours=COLOURS, size=(WIDTH, HEIGHT), boxes=BOXES):
    width, height = size
    projection = perspective(width, height)
    depth, normal = raycast(width, height, projection, boxes, floor_y=FLOOR_Y)
    rays = pixel_rays(width, height, projection)
    floor = np.isclose(normal[..., 1], 1.0) & (depth < CLIP_END)
    _, box_seen, _ = intersect_boxes(np.zeros_like(rays), rays, boxes, depth.astype(np.float64) + 1e-3)
    radiance = np.zeros((height, width, 4), np.float32)
    radiance[box_seen >= 0, :3] = colours[box_seen[box_seen >= 0]]
    surface_roughness = np.where(floor, roughness, 1.0).astype(np.float32)
    return projection, depth, normal, rays, floor, radiance, surface_roughness


def analytic_reflection(projection, depth, rays, floor):
    """(H, W) index of the box each floor pixel's mirror ray shows, where the camera sees that
    point too (SSR can show nothing else); -1 elsewhere."""
    points = rays * depth[..., None]
    mirrored = mirror_image(rays / np.linalg.norm(rays, axis=-1, keepdims=True), axis=1)
    t, box, _ = intersect_boxes(points, mirrored, BOXES, np.full(depth.shape, 1e3))
    seen = seen_by_camera(points + mirrored * t[..., None], projection, depth)
    return np.where(floor & (box >= 0) & seen, box, -1)


def test_mirror_still_shows_the_analytic_mirror_image(gpu_backend):
    """Roughness 0, where the mirror image is the exact answer (any rougher lobe blurs edges
    by its own width). The chain of the last round was off at 855 of these pixels: rays from
    the lobe's tail read wide cones, specks of whatever lay around their hits."""
    projection, depth, normal, rays, floor, radiance, surface_roughness = mirror_scene(0.0)
    expected_box = analytic_reflection(projection, depth, rays, floor)
    # Judge pixels whose whole neighbourhood shows the same box.
    size = 2 * MARGIN_PX + 1
    judged = (expected_box >= 0) & (maximum_filter(expected_box, size) == minimum_filter(expected_box, size))
    assert judged.sum() > 1000, "the scene must show a large mirror image"

    settings = preset("balanced")
    budget = ray_budget(surface_roughness, depth, CLIP_END, settings)
    arrays, _ = run_synthetic_chain(depth, normal, surface_roughness, projection, settings, radiance=radiance,
                                    ray_budget=budget)
    reflection = arrays["reflection"]
    confidence = reflection[..., 3]
    shown = reflection[..., :3] / np.maximum(confidence, 1e-6)[..., None]
    error = np.abs(shown - COLOURS[np.maximum(expected_box, 0)]).max(axis=-1)
    wrong = judged & ((error > TOLERANCE) | (confidence < 0.5))
    assert wrong.sum() <= 0.002 * judged.sum(), (
        f"{wrong.sum()} of {judged.sum()} pixels off the mirror image by more than {TOLERANCE} "
        f"(worst {error[judged].max():.3f}; specks or stair-steps), rows {sorted(set(np.nonzero(wrong)[0]))[:10]}")


def test_sharp_surfaces_always_get_expensive_rays(gpu_backend):
    """The budget's smoothest-first share is not enough where a mirror covers most of the
    frame: there a coin sent most mirror pixels to the cheap linear march, whose coarse steps
    showed as stair-steps. Every traced pixel at most sharp_roughness gets a Hi-Z ray."""
    projection, depth, normal, _, floor, _, surface_roughness = mirror_scene(0.05)
    surface_roughness = np.where(floor, 0.05, 0.3).astype(np.float32)
    settings = preset("balanced").with_overrides(["expensive_ray_budget=0.1", "accumulate_iterations=1",
                                                  "noise_threshold=0", "half_resolution=false"])
    assert floor.mean() > 0.2, "the floor must be more than the budget"
    arrays, _ = run_synthetic_chain(depth, normal, surface_roughness, projection, settings,
                                    ray_budget=ray_budget(surface_roughness, depth, CLIP_END, settings))
    ray_class = arrays["ray_stats"][..., 0]
    traced = ray_class > 0
    assert (ray_class[traced & floor] == 2).all()
    assert (ray_class[traced & ~floor] == 1).all(), "the budget is spent on the sharp floor"


def test_no_seam_where_the_floor_meets_the_wall(gpu_backend):
    """The row of floor pixels touching the back wall mirrors the wall as the rows below it do.
    Its rays hit the wall's bottom row, right at the contact, and a bilinear fetch there read
    half of the floor's own (dark) colour: a dark line across the whole frame."""
    projection, depth, normal, rays, floor, radiance, surface_roughness = mirror_scene(0.04)
    settings = preset("balanced")
    arrays, _ = run_synthetic_chain(depth, normal, surface_roughness, projection, settings, radiance=radiance,
                                    ray_budget=ray_budget(surface_roughness, depth, CLIP_END, settings))
    reflection = arrays["reflection"]
    _, box_seen, _ = intersect_boxes(np.zeros_like(rays), rays, BOXES, depth.astype(np.float64) + 1e-3)
    wall_above = np.zeros_like(floor)
    wall_above[1:] = box_seen[:-1] == 0
    contact = floor & wall_above  # floor pixels right under the back wall
    assert contact.sum() > 100
    shown = reflection[..., :3] / np.maximum(reflection[..., 3:], 1e-6)
    error = np.abs(shown - COLOURS[0]).max(axis=-1)
    wrong = (error > TOLERANCE) | (reflection[..., 3] < 0.9)
    assert wrong[contact].mean() < 0.05, (wrong[contact].sum(), contact.sum(), np.round(shown[wrong & contact][:3], 3))


def rippled_mirror(width, height, amplitude=0.05, wavelength=0.5, stripe_period=0.5):
    """A mirror floor whose normals ripple across it (a corrugated metal sheet; the depth stays
    flat) under the boxes, striped in world space so every pixel's exact hit point shows.
    Returns the G-buffers, the scene's radiance, the floor mask and the exact mirror image: each
    floor pixel's camera ray reflected about its own normal and intersected with the boxes in
    numpy, NaN where the camera does not see the point it hits."""
    def striped(points, box):
        stripes = 0.5 + 0.5 * np.sin(2 * np.pi * points.sum(-1) / stripe_period)
        return COLOURS[np.maximum(box, 0)] * (0.3 + 0.7 * stripes[..., None])
    projection = perspective(width, height)
    depth, normal = raycast(width, height, projection, BOXES, floor_y=FLOOR_Y)
    rays = pixel_rays(width, height, projection)
    floor = np.isclose(normal[..., 1], 1.0) & (depth < CLIP_END)
    points = rays * depth[..., None]
    _, box_seen, _ = intersect_boxes(np.zeros_like(rays), rays, BOXES, depth.astype(np.float64) + 1e-3)
    radiance = np.zeros((height, width, 4), np.float32)
    radiance[box_seen >= 0, :3] = striped(points[box_seen >= 0], box_seen[box_seen >= 0])
    tilt = amplitude * np.sin(2 * np.pi * points[..., 0] / wavelength)
    ripple = np.stack([tilt, np.ones_like(tilt), np.zeros_like(tilt)], -1)
    ripple /= np.linalg.norm(ripple, axis=-1, keepdims=True)
    normal = np.where(floor[..., None], ripple, normal).astype(np.float32)
    view = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    mirrored = view - 2 * np.sum(view * ripple, -1, keepdims=True) * ripple
    t, box, _ = intersect_boxes(points, mirrored, BOXES, np.full(depth.shape, 1e3))
    hits = points + mirrored * t[..., None]
    seen = floor & (box >= 0) & seen_by_camera(hits, projection, depth)
    expected = np.where(seen[..., None], striped(hits, box), np.nan)
    return projection, depth, normal, radiance, floor, expected


def test_a_rippled_mirror_keeps_its_sharp_image_at_half_resolution(gpu_backend):
    """Half-resolution tracing gives a pixel its own ray one iteration in four; in the others its
    neighbours' rays, reflected about normals turned a degree or more from its own, miss its
    narrow lobe, and the still shows their reflections: off by half of what a one-pixel shift
    of the image costs. A mirror pixel traces a ray of its own every iteration (use_sharp_rays, the
    default) and keeps the image sharp: within a third of a one-pixel shift of the exact image."""
    width, height = 320, 180
    projection, depth, normal, radiance, floor, expected = rippled_mirror(width, height)
    roughness = np.where(floor, 0.02, 1.0).astype(np.float32)

    def image_error(settings):
        """(mean error on the judged pixels, what a one-pixel shift of the exact image costs there)."""
        arrays, _ = run_synthetic_chain(depth, normal, roughness, projection, settings, radiance=radiance,
                                        ray_budget=ray_budget(roughness, depth, CLIP_END, settings))
        reflection = arrays["reflection"]
        confidence = reflection[..., 3]
        shown = reflection[..., :3] / np.maximum(confidence, 1e-6)[..., None]
        judged = np.isfinite(expected[..., 0]) & (confidence > 0.5)
        judged[:10], judged[-10:], judged[:, :10], judged[:, -10:] = False, False, False, False
        assert judged.sum() > 5000, "the floor must mirror the boxes"
        one_pixel_shift = np.nanmean(np.abs(np.roll(expected, 1, axis=1) - expected).mean(-1)[judged])
        return np.abs(shown - expected).mean(-1)[judged].mean(), one_pixel_shift

    error, one_pixel_shift = image_error(preset("balanced"))
    assert error <= one_pixel_shift / 3, (
        f"the rippled mirror's image is off by {error:.4f}, {error / one_pixel_shift:.2f} of a one-pixel shift "
        f"({one_pixel_shift:.4f}): blurred")
    reused, _ = image_error(preset("balanced").with_overrides(["use_sharp_rays=false"]))
    assert reused > 1.5 * error, "without its own rays the mirror should show its neighbours' reflections"
