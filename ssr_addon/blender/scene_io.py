"""Opening a scene (a .blend file or a scene-builder script) and reading its camera."""
import os
import runpy
import sys

import bpy
import numpy as np

from ..core.errors import SSRError


def load_scene(path):
    """Open SCENE as the current file and return its scene.

    A `.py` scene is a builder: it defines `build(scene)`, which fills an empty
    factory scene. Its folder goes on sys.path so builders can share helpers.
    """
    if not os.path.isfile(path):
        raise SSRError(f"scene file not found: {path}")
    path = os.path.abspath(path)
    extension = os.path.splitext(path)[1].lower()
    if extension == ".blend":
        try:
            bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
        except RuntimeError as error:
            raise SSRError(f"cannot open {path}: {_first_line(error)}") from None
        return bpy.context.scene
    if extension == ".py":
        return _build_scene(path)
    raise SSRError(f"unsupported scene file {path}: expected a .blend file or a .py scene builder")


def _build_scene(path):
    folder = os.path.dirname(path)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    try:
        namespace = runpy.run_path(path, run_name="ssr_scene_builder")
    except SystemExit as error:  # exiting would end the run with nothing rendered, status 0
        raise SSRError(f"scene builder {path} called sys.exit({error.code}) while loading") from None
    except Exception as error:  # the builder is user code: report, never a traceback
        raise SSRError(f"scene builder {path} failed to load: {type(error).__name__}: {_first_line(error)}") from None
    build = namespace.get("build")
    if not callable(build):
        raise SSRError(f"scene builder {path} defines no build(scene) function")
    # The factory startup file without the factory preferences, which would disable this add-on.
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    try:
        build(scene)
    except SystemExit as error:
        raise SSRError(f"scene builder {path} called sys.exit({error.code}) in build(scene)") from None
    except Exception as error:
        raise SSRError(f"scene builder {path} failed: {type(error).__name__}: {_first_line(error)}") from None
    return scene


def _first_line(error):
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def require_camera(scene):
    if scene.camera is None:
        raise SSRError(f"scene '{scene.name}' has no active camera")
    if scene.camera.type != "CAMERA":
        raise SSRError(f"scene '{scene.name}': active camera '{scene.camera.name}' is not a camera object")
    return scene.camera


def require_square_pixels(scene):
    """Blender 5.0 fails to write the multilayer EXR of a render with passes when pixels are not square."""
    aspect_x, aspect_y = scene.render.pixel_aspect_x, scene.render.pixel_aspect_y
    if aspect_x != aspect_y:
        raise SSRError(f"scene '{scene.name}' has non-square pixels (pixel aspect {aspect_x:g}:{aspect_y:g}), "
                       "which Blender 5.0 cannot write as render passes: set Output > Format > Aspect to 1:1 "
                       "and stretch the finished frames instead")
    return scene


def camera_matrices(scene, width, height):
    """World-to-view and view-to-clip matrices of the scene camera as float32 arrays."""
    camera = require_camera(scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    projection = camera.calc_matrix_camera(
        depsgraph, x=width, y=height,
        scale_x=scene.render.pixel_aspect_x, scale_y=scene.render.pixel_aspect_y)
    view = camera.matrix_world.inverted()
    return np.array(view, dtype=np.float32), np.array(projection, dtype=np.float32)


def shows_a_surface(normal):
    """Where a Normal pass ((H, W, 3)) shows a surface rather than the world, which has no normal."""
    return np.linalg.norm(normal, axis=-1) >= 0.5


def view_depth(position, view_matrix):
    """Distance along the view axis of each pixel's world POSITION ((H, W, 3)), as an (H, W, 1) array."""
    view = np.asarray(view_matrix, np.float32)
    depth = -(position @ view[2, :3] + view[2, 3])
    return depth[..., None].astype(np.float32)
