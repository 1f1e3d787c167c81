"""Whether the rays the screen could not resolve would reach anything: the mirror ray of a
pixel cast through Blender's own BVH (Scene.ray_cast), on the CPU and independent of the
chain's trace.

A ray that leaves the frame towards an open sky needs no capture: the world the probes
fall back to is what it would find. fallback=auto (batch.frame.FrameFallbacks) counts only
the light whose rays would reach geometry.
"""
import bpy
import numpy as np
from mathutils import Vector

from ..core.captures import pixel_footprints
from .scene_captures import world_positions

# Casts per decision at most: beyond that many candidates a random choice of them is cast,
# each standing for the ones not cast (the decision needs a share of the frame's light, not
# a per-pixel answer).
MAX_CASTS = 4096
# The origin leaves the surface by this many pixel footprints, so a ray does not find its own surface.
ORIGIN_OFFSET_PX = 2.0
# Objects a cast may pass through (hidden from the render or from glossy rays) before it gives up.
MAX_PASS_THROUGH = 4


def reaching_geometry(scene, passes, candidates):
    """(H, W) weights: where the mirror ray of a CANDIDATES pixel ((H, W) bool) of PASSES (its
    depth, normal and camera) would hit an object of SCENE the render shows. Every candidate
    gets 1 or 0 where there are at most MAX_CASTS; beyond, MAX_CASTS of them chosen at random
    get 1 / (the share cast) or 0 and the others 0, so that a sum of light over the weights
    is the sum over the pixels that reach, in expectation."""
    reach = np.zeros(candidates.shape, np.float32)
    rows, columns = np.nonzero(candidates)
    if rows.size > MAX_CASTS:
        chosen = np.random.default_rng(0).choice(rows.size, MAX_CASTS, replace=False)
        rows, columns = rows[chosen], columns[chosen]
    if rows.size == 0:
        return reach
    points = world_positions(passes.depth, passes.view_matrix, passes.projection_matrix)[rows, columns]
    normals = passes.normal[rows, columns]
    normals = normals / np.maximum(np.linalg.norm(normals, axis=-1, keepdims=True), 1e-8)
    view_to_world = np.linalg.inv(np.asarray(passes.view_matrix, np.float64))
    orthographic = np.asarray(passes.projection_matrix)[3, 3] == 1.0
    incoming = -np.broadcast_to(view_to_world[:3, 2], points.shape) if orthographic else points - view_to_world[:3, 3]
    incoming = incoming / np.maximum(np.linalg.norm(incoming, axis=-1, keepdims=True), 1e-8)
    mirrored = incoming - 2.0 * np.sum(incoming * normals, axis=-1, keepdims=True) * normals
    offsets = ORIGIN_OFFSET_PX * pixel_footprints(passes.depth, passes.projection_matrix)[rows, columns]
    origins = points + normals * offsets[:, None]
    depsgraph = bpy.context.evaluated_depsgraph_get()
    hits = np.array([_reaches(scene, depsgraph, Vector(origin), Vector(direction), passes.clip_end)
                     for origin, direction in zip(origins, mirrored)], np.float32)
    reach[rows, columns] = hits * (np.count_nonzero(candidates) / rows.size)
    return reach


def _reaches(scene, depsgraph, origin, direction, distance):
    for _ in range(MAX_PASS_THROUGH):
        hit, location, _, _, obj, _ = scene.ray_cast(depsgraph, origin, direction, distance=distance)
        if not hit:
            return False
        if not (obj.hide_render or not obj.visible_glossy):
            return True
        travelled = (location - origin).length + 1e-4
        origin, distance = location + direction * 1e-4, distance - travelled
    return False
