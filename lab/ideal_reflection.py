"""What a correct screen-space reflection would show over an engine's frame, by Monte Carlo
with exact rays: the yardstick that says how much of an error is the chain's own.

For every pixel SSR traces (roughness within max_roughness), directions are drawn from
the visible normals of its GGX lobe (numpy, ssr_addon.core.ggx) and cast into the scene with
Blender's own ray casts (`Scene.ray_cast`), from the surface the camera ray meets. A ray
counts as seen where its first hit is on screen and the camera sees that same point there
(the depth pass agrees); it then shows the engine's Combined at that pixel, as a
screen-space reflection would. Rays that leave the screen, hit what the camera cannot see
or escape to the world are the fallback's: the engine's own probe/world reflection. Each
direction counts by its Smith masking, so the estimate is the normalised lobe integral
the chain's ratio estimator approximates. Nothing here shares code with the shaders.
"""
import bpy
import numpy as np
from mathutils import Vector

from ssr_addon.core.ggx import ggx_alpha, sample_visible_normals, stratified_points, visible_normal_weight
from ssr_addon.core.settings import ChainSettings

SEEN_DEPTH_TOLERANCE = 0.03  # relative: the depth pass is an anti-aliased mean, not one surface
SURFACE_OFFSET = 1e-4        # relative to the distance from the camera: rays start just off the surface


def _pixel_points(passes):
    """(H, W, 3) world positions of the pixel centres at the depth pass's distance, and the camera."""
    height, width = passes.depth.shape
    view, projection = passes.view_matrix.astype(np.float64), passes.projection_matrix.astype(np.float64)
    view_to_world = np.linalg.inv(view)
    rows, columns = np.mgrid[0:height, 0:width]
    ndc_x, ndc_y = (columns + 0.5) / width * 2 - 1, 1 - (rows + 0.5) / height * 2
    depth = passes.depth.astype(np.float64)
    points = np.stack([(ndc_x + projection[0, 2]) * depth / projection[0, 0],
                       (ndc_y + projection[1, 2]) * depth / projection[1, 1], -depth, np.ones_like(depth)], -1)
    return (points @ view_to_world.T)[..., :3], view_to_world[:3, 3]


def _tangent_frame(normal):
    helper = np.array([0.0, 0.0, 1.0]) if abs(normal[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    tangent = np.cross(normal, helper)
    tangent /= np.linalg.norm(tangent)
    return np.stack([tangent, np.cross(normal, tangent), normal], 1)


def ideal_screen_space(scene, passes, samples=64, max_roughness=ChainSettings().max_roughness, seed=0):
    """(reflected radiance premultiplied by confidence (H, W, 3), confidence (H, W)) of a correct
    screen-space reflection of PASSES (an engine's RenderPasses of SCENE's current frame), before
    the specular colour; zero where SSR does not trace."""
    height, width = passes.depth.shape
    rng = np.random.default_rng(seed)
    points, camera = _pixel_points(passes)
    view = passes.view_matrix.astype(np.float64)
    world_to_clip = passes.projection_matrix.astype(np.float64) @ view
    depsgraph = bpy.context.evaluated_depsgraph_get()
    pattern = stratified_points(samples)
    premultiplied, confidence = np.zeros((height, width, 3)), np.zeros((height, width))
    traced = (passes.roughness <= max_roughness) & (np.linalg.norm(passes.normal, axis=-1) > 0.5)
    for row, column in zip(*np.nonzero(traced)):
        incident = points[row, column] - camera
        incident /= np.linalg.norm(incident)
        found, surface, surface_normal, *_ = scene.ray_cast(depsgraph, Vector(camera), Vector(incident))
        normal = passes.normal[row, column].astype(np.float64)
        normal /= np.linalg.norm(normal)
        frame = _tangent_frame(normal)
        view_local = frame.T @ -incident
        if not found or view_local[2] <= 1e-4:
            continue
        alpha = float(ggx_alpha(passes.roughness[row, column]))
        half = sample_visible_normals(view_local[None, None], np.array([[alpha]]), (pattern + rng.random(2)) % 1.0)[0]
        light_local = 2 * (half @ view_local)[:, None] * half - view_local
        weights = visible_normal_weight(view_local[2], light_local[:, 2], alpha ** 2)
        origin = Vector(np.array(surface) + np.array(surface_normal) * SURFACE_OFFSET
                        * np.linalg.norm(np.array(surface) - camera))
        radiance, total, seen = np.zeros(3), weights.sum(), 0.0
        for light, weight in zip(light_local[weights > 0], weights[weights > 0]):
            hit, location, *_ = scene.ray_cast(depsgraph, origin, Vector(frame @ light))
            pixel = _seen_pixel(passes.depth, world_to_clip, view, location) if hit else None
            if pixel is not None:
                radiance += weight * passes.combined[pixel][:3]
                seen += weight
        if total > 0:
            premultiplied[row, column], confidence[row, column] = radiance / total, seen / total
    return premultiplied.astype(np.float32), confidence.astype(np.float32)


def _seen_pixel(depth, world_to_clip, view, location):
    """(row, column) where the camera (VIEW, WORLD_TO_CLIP: float64) sees LOCATION, or None
    (off screen or hidden)."""
    point = np.array([*location, 1.0])
    clip = world_to_clip @ point
    if clip[3] <= 0 or abs(clip[0]) >= clip[3] or abs(clip[1]) >= clip[3]:
        return None
    height, width = depth.shape
    row = min(int((1 - clip[1] / clip[3]) / 2 * height), height - 1)
    column = min(int((clip[0] / clip[3] + 1) / 2 * width), width - 1)
    distance = -(view @ point)[2]
    return (row, column) if abs(depth[row, column] - distance) <= SEEN_DEPTH_TOLERANCE * distance else None


def with_reflection(images, reflected, confidence):
    """The image of IMAGES (a frame's batch.frame.FrameImages) with its probe/world reflection
    replaced by REFLECTED (after the specular colour, premultiplied by CONFIDENCE) where
    CONFIDENCE says, as the chain's composite does. The probe/world reflection is the frame's
    Specular Indirect layer: its lamp highlights split off as the frame's render split them."""
    passes = images.passes
    return (passes.combined[..., :3] + reflected
            - confidence[..., None] * passes.specular_color * images.layers["Specular Indirect"])
