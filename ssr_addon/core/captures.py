"""Views of the scene besides the frame's own, which rays that leave the frame or pass behind
what it shows are traced in ("Beyond the screen"): a large flat reflector's planar capture and
a depth cube map."""
from dataclasses import dataclass

import numpy as np

from .gpu_backend import upload
from .inputs import BACKGROUND_DEPTH


# Rays from pixels this close to the reflector's plane, in pixel footprints at their depth, whose
# normal is this close to its, leave the reflector (planar_trace.glsl, and the reflector's share
# of a frame: blender.scene_captures.reflector_share).
PLANE_TOLERANCE_PX = 2.0
PLANE_NORMAL_COS = 0.99
# World-to-view entries (rotation, and translation in scene units) of a capture camera and of a
# view's mirrored camera that differ by less than this are the same camera: float32's rounding
# at a few hundred units is far below it, a one-degree orbit step far above.
CAPTURE_VIEW_TOLERANCE = 1e-3
_FLIP_X = np.diag((-1.0, 1.0, 1.0, 1.0))


def pixel_footprints(depth, projection_matrix):
    """(H, W) size of one pixel, in view units, at each pixel's DEPTH (common_lib.glsl's
    pixel_footprint)."""
    projection = np.asarray(projection_matrix, np.float64)
    orthographic = projection[3, 3] == 1.0
    return 2.0 / (projection[1, 1] * depth.shape[0]) * (1.0 if orthographic else depth)


@dataclass
class PlanarCapture:
    """The scene as a large flat reflector (a floor, a mirror, water) shows it: rendered from
    the frame's camera mirrored in the reflector's plane, the reflector hidden
    (blender.scene_captures). Arrays in image order, as RenderPasses'."""
    radiance: np.ndarray         # (H, W, 4) the lit scene, scene linear
    depth: np.ndarray            # (H, W) distance along the capture camera's view axis; BACKGROUND_DEPTH: world
    normal: np.ndarray           # (H, W, 3) world-space shading normal
    view_matrix: np.ndarray      # (4, 4) world to the capture camera's view
    projection_matrix: np.ndarray  # (4, 4)
    plane: tuple                 # (nx, ny, nz, d): n.x + d = 0 in world space, n towards what it reflects
    reflector: str = ""          # the reflector's object name
    path_traced: bool = False    # lit by a path tracer (capture_engine=cycles): with the indirect light EEVEE lacks

    def drawn_for(self, view_matrix):
        """Whether this capture's camera is that of the view VIEW_MATRIX (world to view) mirrored:
        then a mirror's rays run along its own view rays. A moving view in the 3D View traces the
        held view's capture, whose camera no longer mirrors it."""
        return bool(np.allclose(mirrored_view(view_matrix, self.plane), self.view_matrix, atol=CAPTURE_VIEW_TOLERANCE))

    def textures(self):
        """The capture as the chain's resources (gpu_passes.PLANAR_TRACE reads them)."""
        return {"capture_radiance": upload(self.radiance), "capture_depth": upload(self.depth),
                "capture_normal": upload(self.normal)}


def planar_capture_matrices(camera, plane):
    """(world to view, view to clip) of the capture camera of PLANE: CAMERA, the (world to view,
    view to clip) of the view the capture serves, mirrored. A mirror is not a rotation, so its x
    axis (and so its lens shift) is flipped back: a camera like any other."""
    view, projection = camera
    return (mirrored_view(view, plane).astype(np.float32),
            (_FLIP_X @ np.asarray(projection, np.float64) @ _FLIP_X).astype(np.float32))


def mirrored_view(view, plane):
    """World to view (float64) of the camera of VIEW (world to view) mirrored in PLANE, its x axis
    flipped back (planar_capture_matrices)."""
    return np.linalg.inv(mirror_matrix(plane) @ np.linalg.inv(np.asarray(view, np.float64)) @ _FLIP_X)


def mirror_matrix(plane):
    """(4, 4) reflection of world space in PLANE (nx, ny, nz, d), n of unit length."""
    normal, offset = np.asarray(plane[:3], np.float64), float(plane[3])
    reflection = np.eye(4)
    reflection[:3, :3] -= 2.0 * np.outer(normal, normal)
    reflection[:3, 3] = -2.0 * offset * normal
    return reflection


# The cube's faces in the order the shader numbers them (cube_trace.glsl: 2 * axis + negative):
# the direction each face camera looks and its up direction.
CUBE_FACES = (((1, 0, 0), (0, 0, 1)), ((-1, 0, 0), (0, 0, 1)), ((0, 1, 0), (0, 0, 1)), ((0, -1, 0), (0, 0, 1)),
              ((0, 0, 1), (0, 1, 0)), ((0, 0, -1), (0, 1, 0)))


def cube_face_views(centre):
    """(6, 4, 4) world to view matrices of the cube's face cameras at CENTRE (Blender's camera
    convention: looking down -Z, Y up)."""
    views = []
    for forward, up in CUBE_FACES:
        back = -np.asarray(forward, np.float64)
        right = np.cross(up, back)
        camera = np.eye(4)
        camera[:3, 0], camera[:3, 1], camera[:3, 2] = right, np.cross(back, right), back
        camera[:3, 3] = centre
        views.append(np.linalg.inv(camera))
    return np.array(views)


def cube_face_projection(clip_start, clip_end):
    """(4, 4) projection of a 90-degree square face."""
    near, far = clip_start, clip_end
    return np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0],
                     [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)], [0, 0, -1.0, 0]])


def cube_atlas(faces):
    """The six FACES ((N, N, C) each, image order, CUBE_FACES order) in one (2N, 3N, C) atlas,
    face f at column f % 3 and row f // 3 counted from the bottom, as the GPU reads it."""
    side = faces[0].shape[0]
    atlas = np.zeros((2 * side, 3 * side) + faces[0].shape[2:], np.float32)
    for index, face in enumerate(faces):
        row = (1 - index // 3) * side  # image order: the bottom row of faces comes last
        atlas[row:row + side, (index % 3) * side:(index % 3 + 1) * side] = face
    return atlas


@dataclass
class CubeCapture:
    """Radiance and distance in six 90-degree faces from CENTRE, a point in free space among
    the reflectors (blender.scene_captures), packed by cube_atlas."""
    radiance: np.ndarray         # (2N, 3N, 4) the lit scene
    depth: np.ndarray            # (2N, 3N) distance along each face camera's view axis; BACKGROUND_DEPTH: world
    centre: tuple                # (x, y, z) world
    face_views: np.ndarray       # (6, 4, 4) cube_face_views(centre)

    @property
    def side(self):
        return self.depth.shape[0] // 2

    @property
    def reach(self):
        """The farthest any surface the cube shows lies from its centre (a face's corner is
        sqrt(3) times its axis distance away)."""
        shown = self.depth[self.depth < BACKGROUND_DEPTH]
        return float(np.sqrt(3.0) * shown.max()) if shown.size else 0.0

    def textures(self):
        """The cube as the chain's resources (gpu_passes.CUBE_TRACE reads them)."""
        return {"cube_radiance": upload(self.radiance), "cube_depth": upload(self.depth)}
