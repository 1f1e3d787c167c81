"""The Vector pass of a moving camera over a still scene (progressive.camera_motion), against
the pinhole camera's own geometry: a point at depth z seen from a camera slid sideways by d
moves f d / z pixels, and the world, at infinity, moves with the camera's turn alone."""
import math

import numpy as np

from ssr_addon.core.inputs import BACKGROUND_DEPTH
from ssr_addon.core.progressive import UNSEEN_MOTION, camera_motion

WIDTH, HEIGHT, LENS_FOCAL = 64, 36, 1.5  # focal length in units of the half-width


def perspective(near=0.1, far=100.0):
    projection = np.zeros((4, 4))
    projection[0, 0], projection[1, 1] = LENS_FOCAL, LENS_FOCAL * WIDTH / HEIGHT
    projection[2, 2], projection[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
    projection[3, 2] = -1.0
    return projection


def view_at(x=0.0, turn=0.0):
    """World to view of a camera at (X, 0, 0) looking down -z, turned by TURN radians about y."""
    camera = np.eye(4)
    camera[:3, :3] = [[math.cos(turn), 0, math.sin(turn)], [0, 1, 0], [-math.sin(turn), 0, math.cos(turn)]]
    camera[0, 3] = x
    return np.linalg.inv(camera)


def test_a_sideways_slide_moves_each_point_by_focal_length_times_slide_over_depth():
    depth = np.full((HEIGHT, WIDTH), 5.0, np.float32)
    depth[:, :10] = 2.5  # a nearer strip moves twice as far
    projection = perspective()
    before = projection @ view_at(0.0)
    motion, shared = camera_motion(depth, view_at(0.1), projection, before)
    focal_pixels = LENS_FOCAL * WIDTH / 2
    assert np.allclose(motion[:, 10:-1, 0], focal_pixels * 0.1 / 5.0, atol=1e-3)
    assert np.allclose(motion[:, :10, 0], focal_pixels * 0.1 / 2.5, atol=1e-3)
    assert np.allclose(motion[:, :-1, 1], 0.0, atol=1e-3)
    # The last column's points lay 0.96 px past the old screen's edge: the camera before did not see them.
    assert np.all(motion[:, -1] == UNSEEN_MOTION)
    assert shared == (WIDTH - 1) / WIDTH


def test_what_the_nearer_strip_hid_from_the_camera_before_was_not_seen():
    """The same slide, with the view before: its strip, 1.92 px further right, hid the far
    plane's column just right of the strip's new edge (now at 10.5 px, then at 11.46, behind
    the strip's edge at 11.92); the next column (then at 12.46) was in sight."""
    depth = np.full((HEIGHT, WIDTH), 5.0, np.float32)
    depth[:, :10] = 2.5
    focal_pixels = LENS_FOCAL * WIDTH / 2
    depth_before = np.full((HEIGHT, WIDTH), 5.0, np.float32)
    strip_edge_before = 10 + focal_pixels * 0.1 / 2.5
    depth_before[:, :int(round(strip_edge_before))] = 2.5  # texel centres left of 11.92
    projection = perspective()
    motion, shared = camera_motion(depth, view_at(0.1), projection, projection @ view_at(0.0), depth_before,
                                   view_at(0.0))
    assert np.all(motion[:, 10] == UNSEEN_MOTION)
    assert np.allclose(motion[:, 11:-1, 0], focal_pixels * 0.1 / 5.0, atol=1e-3)
    assert np.allclose(motion[:, :10, 0], focal_pixels * 0.1 / 2.5, atol=1e-3)  # the strip hides nothing of itself
    assert shared == (WIDTH - 2) / WIDTH


def test_the_world_moves_by_the_turn_alone_and_a_turn_away_shares_nothing():
    depth = np.full((HEIGHT, WIDTH), BACKGROUND_DEPTH, np.float32)
    depth[HEIGHT // 2, WIDTH // 2] = 3.0
    projection = perspective()
    turn = math.radians(2.0)
    motion, _ = camera_motion(depth, view_at(0.0, turn), projection, projection @ view_at(0.0))
    # The centre of the turned view lies TURN off the old view's axis: f tan(turn) pixels.
    centre = motion[HEIGHT // 2 - 1, WIDTH // 2 - 1:WIDTH // 2 + 1, 0].mean()
    assert math.isclose(centre, -LENS_FOCAL * WIDTH / 2 * math.tan(turn), rel_tol=0.05)
    _, shared = camera_motion(np.full((HEIGHT, WIDTH), 4.0, np.float32), view_at(0.0, math.pi), projection,
                              projection @ view_at(0.0))
    assert shared == 0.0
