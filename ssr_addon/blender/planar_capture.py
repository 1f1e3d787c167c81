"""The planar capture of a frame's main flat reflector (core.captures.PlanarCapture): the
scene rendered from the frame's camera mirrored in the reflector's plane, the reflector and
whatever lies wholly behind its plane hidden.

A mirror is not a rotation, so the capture camera is the mirrored camera with its x axis
flipped back (and its lens shift with it): a camera like any other, whose matrices the chain
traces with. The reflector is found from the scene (the largest flat mesh, as the planar
baseline does) and kept only where the frame shows it reflecting (reflector_share).
"""
import os

import bpy
import numpy as np
from mathutils import Matrix, Vector

from ..core.captures import PlanarCapture, mirror_matrix
from ..core.inputs import BACKGROUND_DEPTH
from .baselines import largest_flat_mesh, rendered_geometry
from .exr_render import pass_layer, render_to_exr
from .scene_io import camera_matrices

# Under fallback=auto the frame gets a capture when the reflector holds at least this share of
# its reflected light (the specular colour of every pixel SSR traces from).
AUTO_MIN_REFLECTOR_SHARE = 0.05
# Pixels this close to the plane, relative to their depth, with a normal this close to its,
# are the reflector's.
PLANE_TOLERANCE = 2e-3
PLANE_NORMAL_COS = 0.99


def reflector_plane(scene, reflector):
    """(nx, ny, nz, d) of REFLECTOR's plane in world space, n towards the scene camera."""
    world = reflector.matrix_world
    normal = (world.to_3x3().inverted_safe().transposed() @ Vector((0.0, 0.0, 1.0))).normalized()
    centre = world @ (sum((Vector(corner) for corner in reflector.bound_box), Vector()) / 8.0)
    offset = -normal.dot(centre)
    if normal.dot(scene.camera.matrix_world.translation) + offset < 0.0:
        normal, offset = -normal, -offset
    return (*normal, offset)


def find_reflector(scene):
    """(object, plane) of the scene's main flat reflector facing the camera, or None."""
    reflector = largest_flat_mesh(scene)
    return None if reflector is None else (reflector, reflector_plane(scene, reflector))


def reflector_share(passes, plane, max_roughness):
    """Share of the frame's reflected light (specular colour of the pixels SSR traces from,
    RenderPasses PASSES) that lies on PLANE."""
    traced = (passes.depth < BACKGROUND_DEPTH) & (passes.roughness <= max_roughness)
    weight = np.where(traced, passes.specular_color.mean(axis=-1), 0.0)
    total = weight.sum()
    if not total > 0.0:
        return 0.0
    height, width = passes.depth.shape
    view_to_world = np.linalg.inv(np.asarray(passes.view_matrix, np.float64))
    clip_to_view = np.linalg.inv(np.asarray(passes.projection_matrix, np.float64))
    rows, columns = np.mgrid[0:height, 0:width]
    ndc = np.stack([(columns + 0.5) / width * 2 - 1, 1 - (rows + 0.5) / height * 2], -1)
    near = np.concatenate([ndc, -np.ones_like(ndc[..., :1]), np.ones_like(ndc[..., :1])], -1) @ clip_to_view.T
    far = np.concatenate([ndc, np.ones_like(ndc[..., :1]), np.ones_like(ndc[..., :1])], -1) @ clip_to_view.T
    near, far = near[..., :3] / near[..., 3:], far[..., :3] / far[..., 3:]
    direction = far - near
    with np.errstate(divide="ignore", invalid="ignore"):
        view_points = near + direction * ((-passes.depth[..., None] - near[..., 2:]) / direction[..., 2:])
    points = view_points @ view_to_world[:3, :3].T + view_to_world[:3, 3]
    normal = np.asarray(plane[:3])
    on_plane = (np.abs(points @ normal + plane[3]) <= PLANE_TOLERANCE * np.maximum(passes.depth, 1.0)) \
        & (passes.normal @ normal >= PLANE_NORMAL_COS)
    return float(weight[on_plane & traced].sum() / total)


def _behind_plane(obj, plane):
    normal, offset = Vector(plane[:3]), plane[3]
    return all(normal.dot(obj.matrix_world @ Vector(corner)) + offset < 0.0 for corner in obj.bound_box)


def render_planar_capture(scene, size, reflector, plane, folder, changes):
    """Render SCENE (set up for its frame's passes) from its camera mirrored in PLANE, REFLECTOR
    hidden, at SIZE, into FOLDER; returns the PlanarCapture. Every change goes through CHANGES."""
    camera = scene.camera
    capture_data = camera.data.copy()
    capture_data.shift_x = -camera.data.shift_x
    capture_camera = bpy.data.objects.new("SSR Planar Capture", capture_data)
    scene.collection.objects.link(capture_camera)
    changes.on_restore(lambda: (bpy.data.objects.remove(capture_camera), bpy.data.cameras.remove(capture_data)))
    location, rotation, _ = camera.matrix_world.decompose()
    camera_to_world = np.array(Matrix.LocRotScale(location, rotation, None))
    capture_camera.matrix_world = Matrix((mirror_matrix(plane) @ camera_to_world @ np.diag((-1.0, 1.0, 1.0, 1.0)))
                                         .tolist())
    changes.set(scene, "camera", capture_camera)
    for obj in rendered_geometry(scene):
        if obj == reflector or _behind_plane(obj, plane):
            changes.set(obj, "hide_render", True)
    layers = render_to_exr(scene, os.path.join(folder, "planar_capture.exr"), changes)
    view, projection = camera_matrices(scene, *size)
    normal = pass_layer(layers, "Normal")
    depth = pass_layer(layers, "Depth")[..., 0].copy()
    depth[np.linalg.norm(normal, axis=-1) < 0.5] = BACKGROUND_DEPTH
    return PlanarCapture(pass_layer(layers, "Combined"), depth, np.ascontiguousarray(normal), view, projection,
                         tuple(float(value) for value in plane), reflector.name)
