"""Analytic G-buffers: a camera at the origin looking down -Z at a few planes and boxes.

Depth and normals come from exact ray casts through pixel centres, so tests
know the true geometry behind every pixel.
"""
import numpy as np


def perspective(width, height, fov_y_degrees=60.0, near=0.1, far=100.0):
    focal = 1.0 / np.tan(np.radians(fov_y_degrees) / 2)
    aspect = width / height
    return np.array([
        [focal / aspect, 0, 0, 0],
        [0, focal, 0, 0],
        [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
        [0, 0, -1, 0]], dtype=np.float32)


def pixel_rays(width, height, projection):
    """Unnormalised view-space directions with z = -1 through every pixel centre (image order)."""
    v, u = np.mgrid[0:height, 0:width]
    ndc_x = (u + 0.5) / width * 2 - 1
    ndc_y = 1 - (v + 0.5) / height * 2
    return np.stack([ndc_x / projection[0, 0], ndc_y / projection[1, 1], -np.ones_like(ndc_x, float)], -1)


def raycast(width, height, projection, boxes, floor_y=None, far=100.0):
    """Depth (distance along -Z) and view normals of axis-aligned boxes and an optional floor.

    boxes: list of (min_corner, max_corner). Background pixels get depth `far`.
    """
    rays = pixel_rays(width, height, projection)
    depth = np.full((height, width), far, np.float64)
    normal = np.zeros((height, width, 3), np.float64)
    normal[..., 2] = 1.0
    if floor_y is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = floor_y / rays[..., 1]
        hit = (rays[..., 1] < 0) & (t > 0) & (t < depth)
        depth[hit] = t[hit]
        normal[hit] = (0, 1, 0)
    t, box, face_normal = intersect_boxes(np.zeros_like(rays), rays, boxes, depth)
    hit = box >= 0
    depth[hit] = t[hit]  # rays have z = -1, so t is the view depth
    normal[hit] = face_normal[hit]
    return depth.astype(np.float32), normal.astype(np.float32)


def camera_texel(points, projection, size):
    """(row, column, on screen) of the texel (image order) the camera, PROJECTION over SIZE
    (width, height) pixels, shows each of POINTS (..., 3, view space) in; row and column are 0
    where it is off screen."""
    width, height = size
    clip = points @ np.asarray(projection, np.float64)[:3, :3].T + projection[:3, 3]
    w = -points[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        column = np.floor((clip[..., 0] / w * 0.5 + 0.5) * width)
        row = np.floor((0.5 - clip[..., 1] / w * 0.5) * height)
    on_screen = (w > 0) & (column >= 0) & (column < width) & (row >= 0) & (row < height)
    return np.where(on_screen, row, 0).astype(int), np.where(on_screen, column, 0).astype(int), on_screen


def seen_by_camera(points, projection, depth):
    """Whether the camera (at the origin, PROJECTION, the DEPTH it rendered) sees each of
    POINTS (..., 3, view space) itself, not something in front of it: on screen, and the
    depth there within 5 % of the point's."""
    row, column, on_screen = camera_texel(points, projection, depth.shape[::-1])
    return on_screen & (np.abs(depth[row, column] + points[..., 2]) < 0.05 * -points[..., 2])


def mirror_image(vectors, axis, plane=0.0):
    """VECTORS (..., 3) mirrored in the plane where coordinate AXIS is PLANE: a point's mirror
    image, or (PLANE 0) a direction reflected off that plane. The analytic answer of every
    mirror-floor test: what a perfect mirror shows is the mirror image of what its rays hit."""
    mirrored = np.array(vectors, np.float64, copy=True)
    mirrored[..., axis] = 2.0 * plane - mirrored[..., axis]
    return mirrored


def intersect_boxes(origins, directions, boxes, t_max):
    """Nearest hit of rays ORIGINS + t DIRECTIONS (t > 0, below T_MAX) on axis-aligned BOXES:
    (t, index of the box or -1, outward face normal)."""
    t_best = np.array(t_max, np.float64, copy=True)
    index = np.full(t_best.shape, -1)
    normal = np.zeros(t_best.shape + (3,))
    for number, (low, high) in enumerate(boxes):
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (np.asarray(low, float) - origins) / directions
            t2 = (np.asarray(high, float) - origins) / directions
        t_near = np.nanmax(np.minimum(t1, t2), axis=-1)
        t_far = np.nanmin(np.maximum(t1, t2), axis=-1)
        hit = (t_near <= t_far) & (t_near > 0) & (t_near < t_best)
        axis = np.argmax(np.minimum(t1, t2), axis=-1)
        t_best[hit], index[hit] = t_near[hit], number
        for a in range(3):
            face = hit & (axis == a)
            normal[face] = 0
            normal[face, a] = -np.sign(directions[..., a])[face]
    return t_best, index, normal


def corridor(width=80, height=48, pole_width=0.1):
    """Floor, back wall, a box and a thin pole: reflections of every kind on a mirror floor."""
    projection = perspective(width, height)
    boxes = [((-3.0, -1.0, -9.0), (3.0, 3.0, -8.0)),      # back wall
             ((-1.6, -1.0, -5.5), (-0.4, 0.2, -4.5)),     # box on the floor
             ((0.9, -1.0, -4.05), (0.9 + pole_width, 1.2, -3.95))]  # thin pole
    depth, normal = raycast(width, height, projection, boxes, floor_y=-1.0)
    return depth, normal, projection


def orthographic(width, height, scale=2.0, near=0.1, far=100.0):
    """An orthographic camera seeing `scale` view units across the image height."""
    half_height = scale / 2
    half_width = half_height * width / height
    return np.array([
        [1 / half_width, 0, 0, 0],
        [0, 1 / half_height, 0, 0],
        [0, 0, -2 / (far - near), -(far + near) / (far - near)],
        [0, 0, 0, 1]], dtype=np.float32)


def facing_plane(width=128, height=128, depth=5.0):
    """A plane facing an orthographic camera: every pixel sees it head on (n = v)."""
    normal = np.zeros((height, width, 3), np.float32)
    normal[..., 2] = 1.0
    return np.full((height, width), depth, np.float32), normal, orthographic(width, height)
