"""The planar capture level: a mirror floor under a box whose underside the camera cannot see.

The expected image is geometry: each floor pixel's mirror ray is intersected with the boxes
in numpy, and the face it hits gives the colour. The capture itself is ray cast the same way
from the camera mirrored in the floor (what blender.scene_captures draws), so the test
checks the chain's tracing through it, not a render.
"""
import numpy as np
from scipy.ndimage import maximum_filter, minimum_filter

from gpu_harness import CLIP_END, synthetic_inputs
from synthetic import intersect_boxes, mirror_image, perspective, pixel_rays, raycast
from ssr_addon.core.captures import PlanarCapture, mirror_matrix
from ssr_addon.core.inputs import BACKGROUND_DEPTH
from ssr_addon.core.ray_budget import ray_budget
from ssr_addon.core.settings import preset
from ssr_addon.core.uniforms import RAY_OUTCOMES

WIDTH, HEIGHT = 320, 180
FLOOR_Y = -1.0
PLANE = (0.0, 1.0, 0.0, -FLOOR_Y)  # y + 1 = 0, facing up
# A back wall, a box standing on the floor and one floating above it: the floating box's
# underside faces the floor, where only its reflection shows it.
BOXES = [((-4.0, -1.0, -12.0), (4.0, 3.0, -11.0)),
         ((-2.2, -1.0, -7.0), (-0.8, 0.0, -5.0)),
         ((0.4, -0.55, -6.0), (2.0, -0.1, -4.0))]
COLOURS = np.array([(0.15, 0.2, 0.7), (0.9, 0.8, 0.1), (0.8, 0.15, 0.1)], np.float32)
UNDERSIDE = np.array((0.1, 0.9, 0.2), np.float32)  # every box's bottom face
MARGIN_PX = 2
TOLERANCE = 0.05


def face_colours(box, normal):
    colour = COLOURS[np.maximum(box, 0)]
    colour[normal[..., 1] < -0.5] = UNDERSIDE
    return np.where((box >= 0)[..., None], colour, 0.0)


def capture_camera():
    """World to view of the camera (at the origin, looking down -Z) mirrored in the floor,
    its x axis flipped so that it is a rotation, as a Blender camera must be."""
    return np.linalg.inv(mirror_matrix(PLANE) @ np.diag((-1.0, 1.0, 1.0, 1.0)))


def ray_cast_capture(projection):
    """The capture as the chain receives it: the boxes seen from the mirrored camera, the floor
    hidden."""
    view = capture_camera()
    to_world = np.linalg.inv(view)
    rays = pixel_rays(WIDTH, HEIGHT, projection) @ to_world[:3, :3].T
    origins = np.broadcast_to(to_world[:3, 3], rays.shape)
    t, box, normal = intersect_boxes(origins, rays, BOXES, np.full(rays.shape[:2], BACKGROUND_DEPTH))
    depth = np.where(box >= 0, t, BACKGROUND_DEPTH).astype(np.float32)  # rays have view z = -1
    radiance = np.zeros((HEIGHT, WIDTH, 4), np.float32)
    radiance[..., :3] = face_colours(box, normal)
    return PlanarCapture(radiance, depth, normal.astype(np.float32), view.astype(np.float32), projection, PLANE)


def mirror_floor_scene():
    projection = perspective(WIDTH, HEIGHT)
    depth, normal = raycast(WIDTH, HEIGHT, projection, BOXES, floor_y=FLOOR_Y)
    rays = pixel_rays(WIDTH, HEIGHT, projection)
    floor = np.isclose(normal[..., 1], 1.0) & (depth < CLIP_END)
    _, box_seen, seen_normal = intersect_boxes(np.zeros_like(rays), rays, BOXES, depth.astype(np.float64) + 1e-3)
    radiance = np.zeros((HEIGHT, WIDTH, 4), np.float32)
    radiance[..., :3] = face_colours(box_seen, seen_normal)
    roughness = np.where(floor, 0.0, 1.0).astype(np.float32)
    points = rays * depth[..., None]
    mirrored = mirror_image(rays / np.linalg.norm(rays, axis=-1, keepdims=True), axis=1)
    _, box, hit_normal = intersect_boxes(points, mirrored, BOXES, np.full(depth.shape, 1e3))
    expected = np.where(floor[..., None] & (box >= 0)[..., None], face_colours(box, hit_normal), np.nan)
    underside = floor & (box >= 0) & (hit_normal[..., 1] < -0.5)
    return projection, depth, normal, roughness, radiance, expected, underside


def run(with_capture):
    projection, depth, normal, roughness, radiance, expected, underside = mirror_floor_scene()
    settings = preset("balanced")
    from ssr_addon.core.chain import ChainState, run_chain
    from ssr_addon.core.gpu_backend import download
    inputs = synthetic_inputs(depth, normal, roughness, projection, radiance,
                              ray_budget(roughness, depth, CLIP_END, settings))
    if with_capture:
        inputs.capture = ray_cast_capture(projection)
        inputs.textures.update(inputs.capture.textures())
    state = ChainState.still()
    state.begin_frame(0)
    outputs = run_chain(inputs, settings, state)
    reflection = download(outputs["reflection"])
    return reflection, download(outputs["ray_outcome"]), expected, underside


def wrong_pixels(reflection, expected):
    judged_colour = np.nan_to_num(expected, nan=-1.0)
    key = judged_colour @ np.array([1.0, 10.0, 100.0])
    size = 2 * MARGIN_PX + 1
    judged = ~np.isnan(expected[..., 0]) & (maximum_filter(key, size) == minimum_filter(key, size))
    confidence = reflection[..., 3]
    shown = reflection[..., :3] / np.maximum(confidence, 1e-6)[..., None]
    error = np.abs(shown - judged_colour).max(axis=-1)
    return judged, judged & ((error > TOLERANCE) | (confidence < 0.5))


def test_planar_capture_shows_what_the_camera_cannot_see(gpu_backend):
    """With the capture, the floor mirrors the floating box's underside and everything else as
    the analytic mirror image; without it, screen space cannot show the underside at all."""
    reflection, outcome, expected, underside = run(with_capture=True)
    judged, wrong = wrong_pixels(reflection, expected)
    assert (judged & underside).sum() > 300, "the floor must mirror a large patch of the hidden underside"
    assert wrong.sum() <= 0.005 * judged.sum(), (
        f"{wrong.sum()} of {judged.sum()} mirror pixels wrong ({(wrong & underside).sum()} on the underside), "
        f"rows {sorted(set(np.nonzero(wrong)[0]))[:10]}")
    assert (outcome[..., 3] == RAY_OUTCOMES["planar"]).any()

    plain, plain_outcome, _, _ = run(with_capture=False)
    _, plain_wrong = wrong_pixels(plain, expected)
    assert (plain_wrong & judged & underside).sum() > 0.9 * (judged & underside).sum(), \
        "screen space alone cannot show the underside"
    assert not (plain_outcome[..., 3] == RAY_OUTCOMES["planar"]).any()

