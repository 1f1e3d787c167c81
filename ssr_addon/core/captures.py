"""Views of the scene besides the frame's own, which rays that leave the frame or pass behind
what it shows are traced in ("Beyond the screen"): a large flat reflector's planar capture."""
from dataclasses import dataclass

import numpy as np

from .gpu_backend import upload


@dataclass
class PlanarCapture:
    """The scene as a large flat reflector (a floor, a mirror, water) shows it: rendered from
    the frame's camera mirrored in the reflector's plane, the reflector hidden
    (blender.planar_capture). Arrays in image order, as RenderPasses'."""
    radiance: np.ndarray         # (H, W, 4) the lit scene, scene linear
    depth: np.ndarray            # (H, W) distance along the capture camera's view axis; BACKGROUND_DEPTH: world
    normal: np.ndarray           # (H, W, 3) world-space shading normal
    view_matrix: np.ndarray      # (4, 4) world to the capture camera's view
    projection_matrix: np.ndarray  # (4, 4)
    plane: tuple                 # (nx, ny, nz, d): n.x + d = 0 in world space, n towards what it reflects
    reflector: str = ""          # the reflector's object name

    def textures(self):
        """The capture as the chain's resources (gpu_passes.PLANAR_TRACE reads them)."""
        return {"capture_radiance": upload(self.radiance), "capture_depth": upload(self.depth),
                "capture_normal": upload(self.normal)}


def mirror_matrix(plane):
    """(4, 4) reflection of world space in PLANE (nx, ny, nz, d), n of unit length."""
    normal, offset = np.asarray(plane[:3], np.float64), float(plane[3])
    reflection = np.eye(4)
    reflection[:3, :3] -= 2.0 * np.outer(normal, normal)
    reflection[:3, 3] = -2.0 * offset * normal
    return reflection
