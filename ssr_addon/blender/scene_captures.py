"""The scene captures the fallback hierarchy traces in (core.captures), drawn or rendered.

The planar capture of a frame's main flat reflector (PlanarCapture): the scene seen from the
frame's camera mirrored in the reflector's plane, the reflector and whatever lies wholly
behind its plane hidden.

A mirror is not a rotation, so the capture camera is the mirrored camera with its x axis
flipped back (and its lens shift with it): a camera like any other, whose matrices the chain
traces with. The reflector is found from the scene (the largest flat mesh, as the planar
baseline does) and kept only where the frame shows it reflecting (reflector_share).

A capture is a render of its own (render_planar_capture, render_cube_capture), or drawn
through a 3D View (GPUOffScreen.draw_view3d: Combined at the frame's samples, the data passes
at one), as close to a 64-sample render as a 16-sample render is, and for the cube's six faces
several times cheaper (lab/capture_cost.py, docs/measurements.md). Between the frame's renders,
though, one run of three frames rendered each frame 13 s slower after drawn captures (the
render and viewport pipelines compiling EEVEE's shaders again for each other), where the lab's
one render after a draw was 5 % slower: until that is settled, runs render their captures
(SceneCaptures without a viewport).

The depth cube map (CubeCapture): six 90-degree faces from where the cubemap baseline puts its
probe, each face's radiance and axis distance.
"""
import os

import bpy
import numpy as np
from mathutils import Matrix, Vector

from ..core.captures import (PLANE_NORMAL_COS, PLANE_TOLERANCE_PX, CubeCapture, PlanarCapture, cube_atlas,
                             cube_face_projection, cube_face_views, pixel_footprints, planar_capture_matrices)
from ..core.errors import SSRError
from ..core.inputs import BACKGROUND_DEPTH
from .baselines import default_probe_placement, rendered_geometry
from .exr_render import pass_layer, render_to_exr
from .overrides import TemporaryChanges
from .scene_io import camera_matrices, shows_a_surface, view_depth

# Under fallback=auto the frame gets a capture when the reflector holds at least this share of
# its reflected light (the specular colour of every pixel SSR traces from).
AUTO_MIN_REFLECTOR_SHARE = 0.05
# A reflector is a plane or a slab this thin against its size; of the largest few, the one
# holding most of the frame's reflected light.
REFLECTOR_THINNESS = 0.02
REFLECTOR_CANDIDATES = 4
# capture_engine=cycles: samples per pixel of a capture, denoised.
CYCLES_CAPTURE_SAMPLES = 32


def _thin_axis(obj):
    """(local axis, half thickness, area in world units) of a mesh thin along one local axis
    (a plane, or a slab: a floor, a table top, a mirror), or None."""
    if obj.type != "MESH":
        return None
    low, high = Vector(map(min, zip(*obj.bound_box))), Vector(map(max, zip(*obj.bound_box)))
    scale = obj.matrix_world.to_scale()
    size = [abs((high[axis] - low[axis]) * scale[axis]) for axis in range(3)]
    axis = min(range(3), key=size.__getitem__)
    across = [size[other] for other in range(3) if other != axis]
    if min(across) <= 0.0 or size[axis] > REFLECTOR_THINNESS * max(across):
        return None
    return axis, (high[axis] - low[axis]) / 2.0, across[0] * across[1]


def reflector_plane(reflector, viewpoint, axis=2, half_thickness=0.0):
    """(nx, ny, nz, d) of the face of REFLECTOR across its local AXIS that faces VIEWPOINT (a
    world position: the camera's), HALF_THICKNESS from its centre in local units, n towards
    the viewpoint."""
    world = reflector.matrix_world
    local_axis = Vector([1.0 if index == axis else 0.0 for index in range(3)])
    local_centre = sum((Vector(corner) for corner in reflector.bound_box), Vector()) / 8.0
    normal = (world.to_3x3().inverted_safe().transposed() @ local_axis).normalized()
    camera = Vector(viewpoint)
    side = 1.0 if normal.dot(camera - world @ local_centre) >= 0.0 else -1.0
    face = world @ (local_centre + local_axis * half_thickness * side)
    normal *= side
    return tuple(float(value) for value in (*normal, -normal.dot(face)))


def find_reflector(scene, passes, max_roughness):
    """(object, plane, share) of the scene's main flat reflector: of its REFLECTOR_CANDIDATES
    largest planes and slabs, the one whose plane holds most of the frame's reflected light
    (reflector_share of PASSES), or None where there is none. The plane faces the camera
    PASSES were seen from."""
    viewpoint = np.linalg.inv(np.asarray(passes.view_matrix, np.float64))[:3, 3]
    thin = [(obj, found) for obj in rendered_geometry(scene) if (found := _thin_axis(obj)) is not None]
    thin.sort(key=lambda candidate: -candidate[1][2])
    best = None
    for obj, (axis, half_thickness, _) in thin[:REFLECTOR_CANDIDATES]:
        plane = reflector_plane(obj, viewpoint, axis, half_thickness)
        share = reflector_share(passes, plane, max_roughness)
        if best is None or share > best[2]:
            best = (obj, plane, share)
    return best


def reflector_share(passes, plane, max_roughness):
    """Share of the frame's reflected light (specular colour of the pixels SSR traces from,
    RenderPasses PASSES) that lies on PLANE."""
    traced = (passes.depth < BACKGROUND_DEPTH) & (passes.roughness <= max_roughness)
    weight = np.where(traced, passes.specular_color.mean(axis=-1), 0.0)
    total = weight.sum()
    if not total > 0.0:
        return 0.0
    points = world_positions(passes.depth, passes.view_matrix, passes.projection_matrix)
    normal = np.asarray(plane[:3])
    footprint = pixel_footprints(np.minimum(passes.depth, 1e6), passes.projection_matrix)
    on_plane = (np.abs(points @ normal + plane[3]) <= PLANE_TOLERANCE_PX * footprint) \
        & (passes.normal @ normal >= PLANE_NORMAL_COS)
    return float(weight[on_plane & traced].sum() / total)


def world_positions(depth, view_matrix, projection_matrix):
    """(H, W, 3) world position of each pixel centre at its view DEPTH (image order)."""
    height, width = depth.shape
    view_to_world = np.linalg.inv(np.asarray(view_matrix, np.float64))
    clip_to_view = np.linalg.inv(np.asarray(projection_matrix, np.float64))
    rows, columns = np.mgrid[0:height, 0:width]
    ndc = np.stack([(columns + 0.5) / width * 2 - 1, 1 - (rows + 0.5) / height * 2], -1)
    ends = [np.concatenate([ndc, np.full_like(ndc[..., :1], z), np.ones_like(ndc[..., :1])], -1) @ clip_to_view.T
            for z in (-1.0, 1.0)]
    near, far = (end[..., :3] / end[..., 3:] for end in ends)
    direction = far - near
    with np.errstate(divide="ignore", invalid="ignore"):
        view_points = near + direction * ((-depth[..., None] - near[..., 2:]) / direction[..., 2:])
    return view_points @ view_to_world[:3, :3].T + view_to_world[:3, 3]


def _hidden_for_capture(scene, reflector, plane):
    """The objects a capture of PLANE leaves out: the reflector and what lies wholly behind it."""
    normal, offset = Vector(plane[:3]), plane[3]

    def behind(obj):
        return all(normal.dot(obj.matrix_world @ Vector(corner)) + offset < 0.0 for corner in obj.bound_box)
    return [obj for obj in rendered_geometry(scene) if obj == reflector or behind(obj)]


def _capture(scene, reflector, plane, view, projection, radiance, normal, depth):
    depth = depth.copy()
    depth[~shows_a_surface(normal)] = BACKGROUND_DEPTH
    return PlanarCapture(np.ascontiguousarray(radiance, dtype=np.float32), depth.astype(np.float32),
                         np.ascontiguousarray(normal, dtype=np.float32), view, projection, plane, reflector.name,
                         path_traced=scene.render.engine == "CYCLES")


def draw_planar_capture(scene, view_layer, viewport, camera, size, samples, reflector, plane, changes):
    """The PlanarCapture of PLANE for the view CAMERA (world to view, view to clip) at SIZE,
    drawn through VIEWPORT (viewport_capture.ViewportCapture): Combined at SAMPLES, normals and
    positions at one. Hides through CHANGES."""
    for obj in _hidden_for_capture(scene, reflector, plane):
        changes.set(obj, "hide_viewport", True)
    view, projection = planar_capture_matrices(camera, plane)
    layers = viewport.draw_passes(scene, view_layer, view, projection, size, {
        "Combined": ("COMBINED", 4, samples), "Normal": ("NORMAL", 3, 1), "Position": ("POSITION", 3, 1)})
    return _capture(scene, reflector, plane, view, projection, layers["Combined"], layers["Normal"],
                    view_depth(layers["Position"], view)[..., 0])


def render_planar_capture(scene, size, reflector, plane, folder, changes):
    """The PlanarCapture of PLANE for the scene camera's view as a render of SCENE (set up for
    its frame's passes) from a capture camera, at SIZE, into FOLDER. Every change goes through
    CHANGES."""
    camera = scene.camera
    capture_data = camera.data.copy()
    capture_data.shift_x = -camera.data.shift_x
    capture_camera = bpy.data.objects.new("SSR Planar Capture", capture_data)
    scene.collection.objects.link(capture_camera)
    changes.on_restore(lambda: (bpy.data.objects.remove(capture_camera), bpy.data.cameras.remove(capture_data)))
    view, _ = planar_capture_matrices(camera_matrices(scene, *size), plane)
    capture_camera.matrix_world = Matrix(np.linalg.inv(np.asarray(view, np.float64)).tolist())
    changes.set(scene, "camera", capture_camera)
    for obj in _hidden_for_capture(scene, reflector, plane):
        # Out of the capture camera's sight only: a path tracer's light still meets it (the
        # reflector hides the sky below what it mirrors, and mirrors light onto it).
        changes.set(obj, "visible_camera", False)
    layers = render_to_exr(scene, os.path.join(folder, "planar_capture.exr"), changes)
    view, projection = camera_matrices(scene, *size)
    return _capture(scene, reflector, plane, view, projection, pass_layer(layers, "Combined"),
                    pass_layer(layers, "Normal"), pass_layer(layers, "Depth")[..., 0])


def cube_centre(scene):
    """Where the depth cube map is captured: where the cubemap baseline puts its probe, in free
    space over the middle of the scene (baselines.default_probe_placement)."""
    return tuple(float(value) for value in default_probe_placement(scene).location)


def _cube_clip(scene, centre):
    """(clip_start, clip_end) of the cube's faces: everything the scene holds, from close by."""
    low, high = _scene_bounds(scene)
    size = (high - low).length
    reach = max((Vector(corner) - Vector(centre)).length for corner in
                [(x, y, z) for x in (low.x, high.x) for y in (low.y, high.y) for z in (low.z, high.z)])
    return size * 1e-3 + 1e-3, reach * 2.0 + 1.0


def _scene_bounds(scene):
    corners = [obj.matrix_world @ Vector(corner) for obj in rendered_geometry(scene) for corner in obj.bound_box]
    if not corners:
        raise SSRError(f"fallback=cube: scene '{scene.name}' has no visible geometry to capture")
    return Vector(map(min, zip(*corners))), Vector(map(max, zip(*corners)))


def draw_cube_capture(scene, view_layer, viewport, side, samples):
    """The CubeCapture of SCENE drawn through VIEWPORT: each face's Combined at SAMPLES, its
    normals (for where the world shows) and positions at one."""
    centre = cube_centre(scene)
    views = cube_face_views(centre)
    projection = cube_face_projection(*_cube_clip(scene, centre))
    radiance, depth = [], []
    for view in views:
        layers = viewport.draw_passes(scene, view_layer, view, projection, (side, side), {
            "Combined": ("COMBINED", 4, samples), "Normal": ("NORMAL", 3, 1), "Position": ("POSITION", 3, 1)})
        face_depth = view_depth(layers["Position"], view)[..., 0]
        face_depth[~shows_a_surface(layers["Normal"])] = BACKGROUND_DEPTH
        radiance.append(layers["Combined"])
        depth.append(face_depth)
    return CubeCapture(cube_atlas(radiance), cube_atlas(depth), centre, views)


def render_cube_capture(scene, side, folder, changes):
    """The CubeCapture of SCENE as six renders (set up for its frame's passes) from a 90-degree
    camera at the cube's centre, into FOLDER. Every change goes through CHANGES."""
    centre = cube_centre(scene)
    views = cube_face_views(centre)
    data = bpy.data.cameras.new("SSR Cube Capture")
    data.angle, data.sensor_fit = np.pi / 2, "HORIZONTAL"
    data.clip_start, data.clip_end = _cube_clip(scene, centre)
    camera = bpy.data.objects.new("SSR Cube Capture", data)
    scene.collection.objects.link(camera)
    changes.on_restore(lambda: (bpy.data.objects.remove(camera), bpy.data.cameras.remove(data)))
    changes.set(scene, "camera", camera)
    changes.set_all(scene.render, resolution_x=side, resolution_y=side)
    radiance, depth = [], []
    for index, view in enumerate(views):
        camera.matrix_world = Matrix(np.linalg.inv(view).tolist())
        layers = render_to_exr(scene, os.path.join(folder, f"cube_face{index}.exr"), changes)
        face_depth = pass_layer(layers, "Depth")[..., 0].copy()
        face_depth[~shows_a_surface(pass_layer(layers, "Normal"))] = BACKGROUND_DEPTH
        radiance.append(pass_layer(layers, "Combined"))
        depth.append(face_depth)
    return CubeCapture(cube_atlas(radiance), cube_atlas(depth), centre, views)


class SceneCaptures:
    """The captures of a run of frames or of views (the planar capture, the depth cube map):
    drawn through a 3D View (VIEWPORT: a viewport_capture.ViewportCapture, shaded as the views
    it captures are), or rendered (VIEWPORT None), and reused while nothing they show changed
    (capture_key): a still camera over a static set is captured once a shot, and the cube,
    which does not follow the camera, while the set holds still."""

    def __init__(self, viewport=None):
        self.viewport = viewport
        self._kept = {}  # level: (key, capture)
        self.made = []   # the levels captured afresh, in order, since the run began

    def _reuse(self, level, key, make):
        """The capture of LEVEL kept under KEY, or MAKE(changes) afresh: what MAKE changes (a
        capture camera, hidden objects, the engine) is undone before anything else looks at
        the scene, so one capture never sees another's set-up."""
        kept = self._kept.get(level)
        if kept is None or kept[0] != key:
            with TemporaryChanges() as changes:
                kept = self._kept[level] = (key, make(changes))
            self.made.append(level)
        return kept[1]

    def _draws(self, setup):
        return self.viewport is not None and setup.engine == "eevee" and setup.capture_engine == "eevee"

    @staticmethod
    def use_capture_engine(scene, setup, changes):
        """Through CHANGES, render with setup.capture_engine: Cycles at CYCLES_CAPTURE_SAMPLES,
        denoised, where it asks for Cycles."""
        if setup.capture_engine == "cycles" and scene.render.engine != "CYCLES":
            changes.set(scene.render, "engine", "CYCLES")
            changes.set(scene.cycles, "samples", CYCLES_CAPTURE_SAMPLES)
            changes.set(scene.cycles, "use_denoising", True)
            changes.set(scene.cycles, "device", "CPU")

    def planar(self, scene, view_layer, setup, passes, folder):
        """The PlanarCapture SETUP asks for of the frame's PASSES, or None: with planar_capture
        auto, only where the main reflector holds AUTO_MIN_REFLECTOR_SHARE of the frame's
        reflected light; on, wherever the scene has a flat mesh. SCENE is set up for the frame's
        render."""
        if setup.planar_capture == "off":
            return None
        found = find_reflector(scene, passes, setup.max_roughness)
        if found is None:
            if setup.planar_capture == "on":
                raise SSRError(f"fallback=planar: scene '{scene.name}' has no flat mesh to capture the reflection of")
            return None
        if setup.planar_capture == "auto" and found[2] < AUTO_MIN_REFLECTOR_SHARE:
            return None
        found = found[:2]
        size = setup.rendered_size
        camera = (np.asarray(passes.view_matrix, np.float64), np.asarray(passes.projection_matrix, np.float64))
        key = (capture_key(scene), tuple(np.round(np.concatenate(camera), 6).ravel()), size, setup.samples,
               setup.engine, setup.capture_engine, found[1])
        if self._draws(setup):
            return self._reuse("planar", key, lambda changes: draw_planar_capture(
                scene, view_layer, self.viewport, camera, size, setup.samples, *found, changes))

        def render(changes):
            self.use_capture_engine(scene, setup, changes)
            return render_planar_capture(scene, size, *found, folder, changes)
        return self._reuse("planar", key, render)

    def cube(self, scene, view_layer, setup, folder):
        """The CubeCapture SETUP asks for (setup.cube_size: the pixels of a face's side; 0: none)."""
        if not setup.cube_size:
            return None
        key = (capture_key(scene), setup.cube_size, setup.samples, setup.engine,
               setup.capture_engine)
        if self._draws(setup):
            return self._reuse("cube", key, lambda changes: draw_cube_capture(scene, view_layer, self.viewport,
                                                                              setup.cube_size, setup.samples))

        def render(changes):
            self.use_capture_engine(scene, setup, changes)
            return render_cube_capture(scene, setup.cube_size, folder, changes)
        return self._reuse("cube", key, render)

    def release(self):
        if self.viewport is not None:
            self.viewport.release()
        self._kept.clear()


def capture_key(scene):
    """What a capture of SCENE shows, as a value that changes when any of it does: every
    object's transform and visibility but the camera's (a planar capture keys on the view it
    serves as well), and the frame where anything else is animated (a material, a light, the
    world)."""
    objects = tuple((obj.name, tuple(map(tuple, obj.matrix_world)), obj.hide_render)
                    for obj in scene.objects if obj != scene.camera)
    animated = any(getattr(block, "animation_data", None) is not None and block.animation_data.action is not None
                   for collection in (bpy.data.materials, bpy.data.lights, bpy.data.worlds, bpy.data.node_groups)
                   for block in collection) or any(
                       getattr(block, "node_tree", None) is not None and block.node_tree.animation_data is not None
                       for collection in (bpy.data.materials, bpy.data.worlds) for block in collection)
    return objects, scene.frame_current if animated else None
