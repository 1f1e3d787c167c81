"""The guard band level: the frame rendered wider, traced whole, the requested frame written.

Checked two ways: where no ray leaves the plain frame, the banded frame's reflection is the
plain one's; where rays do leave it, the band resolves them as the plain frame cannot. And
the widened Blender camera puts every world point exactly the band's pixels further in.
"""
import numpy as np
import pytest
from scipy.ndimage import maximum_filter, minimum_filter

from gpu_harness import CLIP_END, synthetic_inputs
from synthetic import perspective
from ssr_addon.core.inputs import crop_image
from ssr_addon.core.ray_budget import ray_budget
from ssr_addon.core.settings import preset
from ssr_addon.core.uniforms import RAY_OUTCOMES

WIDTH, HEIGHT, BAND = 240, 136, 16
FLOOR_Y = -1.0
# A back wall that fills the frame's top and runs on above it, and a box on the floor.
BOXES = [((-30.0, -1.0, -12.0), (30.0, 20.0, -11.0)),
         ((-1.6, -1.0, -5.5), (0.4, 0.0, -3.5))]
COLOURS = np.array([(0.15, 0.2, 0.7), (0.9, 0.8, 0.1)], np.float32)


def camera_to_world():
    """A camera 1.5 above the floor, pitched 25 degrees down: the wall's top leaves the frame,
    and the floor mirrors it."""
    pitch = np.radians(-25.0)
    rotation = np.array([[1, 0, 0], [0, np.cos(pitch), -np.sin(pitch)], [0, np.sin(pitch), np.cos(pitch)]])
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = rotation, (0.0, FLOOR_Y + 1.5, 0.0)
    return matrix


def mirror_frame(width, height, projection):
    """Depth, world normal, roughness and radiance of the scene through a WIDTH x HEIGHT frame."""
    from synthetic import intersect_boxes, pixel_rays
    to_world = camera_to_world()
    rays = pixel_rays(width, height, projection) @ to_world[:3, :3].T  # view z = -1
    origins = np.broadcast_to(to_world[:3, 3], rays.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_floor = np.where(rays[..., 1] < 0, (FLOOR_Y - origins[..., 1]) / rays[..., 1], np.inf)
    t, box, normal = intersect_boxes(origins, rays, BOXES, np.minimum(t_floor, CLIP_END))
    floor = (box < 0) & np.isfinite(t_floor) & (t_floor < CLIP_END)
    normal[floor] = (0.0, 1.0, 0.0)
    depth = np.where(box >= 0, t, np.where(floor, t_floor, CLIP_END)).astype(np.float32)
    radiance = np.zeros((height, width, 4), np.float32)
    radiance[box >= 0, :3] = COLOURS[box[box >= 0]]
    points = origins + rays * depth[..., None]
    # The wall's upper part is another colour: the floor's far half mirrors it from above the frame.
    radiance[(box == 0) & (points[..., 1] > 1.5), :3] = (0.9, 0.3, 0.6)
    roughness = np.where(floor, 0.0, 1.0).astype(np.float32)
    return depth, normal.astype(np.float32), roughness, radiance


def run(band):
    from ssr_addon.core.chain import ChainState, run_chain
    from ssr_addon.core.gpu_backend import download
    from ssr_addon.core.layers import upsample_nearest
    plain = perspective(WIDTH, HEIGHT)
    width, height = WIDTH + 2 * band, HEIGHT + 2 * band
    projection = (np.diag((WIDTH / width, HEIGHT / height, 1.0, 1.0)) @ plain).astype(np.float32)
    depth, normal, roughness, radiance = mirror_frame(width, height, projection)
    settings = preset("balanced")
    inputs = synthetic_inputs(depth, normal, roughness, projection, radiance,
                              ray_budget(roughness, depth, CLIP_END, settings),
                              view_matrix=np.linalg.inv(camera_to_world()).astype(np.float32))
    crop = (band, band, WIDTH, HEIGHT)
    inputs.frame_rect = (band, band, band + WIDTH, band + HEIGHT)
    state = ChainState.still()
    state.begin_frame(0)
    outputs = run_chain(inputs, settings, state)
    outcome = upsample_nearest(download(outputs["ray_outcome"]), 2, (height, width))
    return (crop_image(download(outputs["reflection"]), crop), crop_image(outcome, crop)[..., 3],
            crop_image(roughness, crop))


def test_guard_band_changes_nothing_where_no_ray_leaves_the_frame(gpu_backend):
    plain, plain_outcome, floor = run(0)
    banded, banded_outcome, _ = run(BAND)
    floor = floor == 0.0
    settled = (plain_outcome == RAY_OUTCOMES["screen"]) & (plain[..., 3] > 0.999)
    # The spatial filter mixes each pixel with its neighbours out to denoise_radius.
    reach = int(np.ceil(preset("balanced").denoise_radius)) + 1
    inside = floor & ~maximum_filter(floor & ~settled, 2 * reach + 1)
    assert inside.sum() > 1000
    difference = np.abs(banded[..., :4] - plain[..., :4]).max(axis=-1)
    assert np.quantile(difference[inside], 0.99) < 0.02, np.quantile(difference[inside], [0.5, 0.9, 0.99, 1.0])

    # Where the plain frame's rays left it, the band resolves those that land just outside, with
    # the colour of the analytic mirror image.
    by_band = floor & (plain_outcome == RAY_OUTCOMES["left_frame"]) & (banded_outcome == RAY_OUTCOMES["guard_band"])
    assert by_band.sum() > 1000
    gained = banded[..., 3] - plain[..., 3]
    # Hits deep in the band fade out towards its outer edge (border_fade), as at a plain frame's.
    assert gained[by_band].mean() > 0.5 and (gained[by_band] > 0.1).mean() > 0.95
    shown = banded[..., :3] / np.maximum(banded[..., 3:], 1e-6)
    expected = mirror_image_colour()
    key = expected @ np.array([1.0, 10.0, 100.0])
    uniform = maximum_filter(key, 5) == minimum_filter(key, 5)  # 2 px from an edge of the mirror image
    error = np.abs(shown - expected).max(axis=-1)
    assert (error[by_band & uniform] < 0.05).mean() > 0.95


def mirror_image_colour():
    """(H, W, 3) colour the requested frame's floor pixels mirror, from the geometry."""
    from synthetic import intersect_boxes, pixel_rays
    to_world = camera_to_world()
    projection = perspective(WIDTH, HEIGHT)
    depth, _, roughness, _ = mirror_frame(WIDTH, HEIGHT, projection)
    rays = pixel_rays(WIDTH, HEIGHT, projection) @ to_world[:3, :3].T
    points = to_world[:3, 3] + rays * depth[..., None]
    mirrored = rays * (1.0, -1.0, 1.0)
    t, box, _ = intersect_boxes(points, mirrored, BOXES, np.full(depth.shape, 1e3))
    colour = np.where((box >= 0)[..., None], COLOURS[np.maximum(box, 0)], 0.0)
    hit_height = (points + mirrored * t[..., None])[..., 1]
    colour[(box == 0) & (hit_height > 1.5)] = (0.9, 0.3, 0.6)
    return colour


@pytest.mark.blender
def test_widened_camera_moves_every_point_by_the_band(tmp_path):
    """Perspective and orthographic cameras with lens shift: a world point's pixel in the widened
    render is its pixel in the frame plus the band, so the frame is the render's centre crop."""
    import bpy
    from ssr_addon.blender.overrides import TemporaryChanges
    from ssr_addon.blender.render_setup import decide_render, widen_camera
    from ssr_addon.blender.scene_io import camera_matrices
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    data = bpy.data.cameras.new("Camera")
    camera = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(camera)
    scene.camera = camera
    camera.location = (1.0, -6.0, 2.0)
    camera.rotation_euler = (1.2, 0.1, 0.3)
    points = np.array([(0.3, 0.5, 1.1, 1.0), (-1.0, 2.0, 0.2, 1.0), (2.0, 1.0, 2.5, 1.0)])
    for kind, fit, size in (("PERSP", "AUTO", (320, 180)), ("PERSP", "VERTICAL", (180, 320)),
                            ("ORTHO", "AUTO", (200, 300)), ("PERSP", "HORIZONTAL", (320, 180))):
        data.type, data.sensor_fit = kind, fit
        data.shift_x, data.shift_y = 0.12, -0.07
        scene.render.resolution_x, scene.render.resolution_y = size
        setup = decide_render(scene, resolution=size, guard_band=0.06)
        bx, by = setup.guard_band
        assert bx > 0 and by > 0 and bx % 2 == 0 and by % 2 == 0

        def pixels(width, height):
            view, projection = camera_matrices(scene, width, height)
            clip = points @ (np.asarray(projection, np.float64) @ np.asarray(view, np.float64)).T
            ndc = clip[:, :2] / clip[:, 3:]
            return (ndc * 0.5 + 0.5) * (width, height)
        plain = pixels(*size)
        with TemporaryChanges() as changes:
            widen_camera(scene, setup, changes)
            banded = pixels(*setup.rendered_size)
        np.testing.assert_allclose(banded, plain + (bx, by), atol=1e-3, err_msg=f"{kind} {fit}")
        np.testing.assert_allclose(pixels(*size), plain, atol=1e-9, err_msg="the camera is restored")
