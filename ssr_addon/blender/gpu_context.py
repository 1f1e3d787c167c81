"""Bringing up Blender's GPU backend, which background mode starts only once a render has run."""
import bpy
import gpu

from ..core.errors import SSRError

_backend_ready = False


def ensure_backend():
    """Bring up the GPU backend; in background mode `gpu` is unusable until a render ran.

    A 1x1 Workbench render of a throw-away scene (with its own camera) starts it
    without touching the user's scenes.
    """
    global _backend_ready
    if _backend_ready:
        return
    if bpy.app.background:
        scene = bpy.data.scenes.new("ssr_gpu_startup")
        camera_data = bpy.data.cameras.new("ssr_gpu_startup")
        camera = bpy.data.objects.new("ssr_gpu_startup", camera_data)
        try:
            scene.collection.objects.link(camera)
            scene.camera = camera
            scene.render.engine = "BLENDER_WORKBENCH"
            scene.render.resolution_x = scene.render.resolution_y = 1
            bpy.ops.render.render(write_still=False, scene=scene.name)
        except RuntimeError as error:
            raise SSRError(f"no GPU context: the start-up render failed ({str(error).strip()})") from None
        finally:
            bpy.data.objects.remove(camera)
            bpy.data.cameras.remove(camera_data)
            bpy.data.scenes.remove(scene)
    try:
        gpu.platform.backend_type_get()
        probe = gpu.types.GPUTexture((1, 1), format="R32F")
        del probe
    except Exception as error:  # gpu raises SystemError/RuntimeError without a context
        raise SSRError(f"no GPU context: {error}") from None
    _backend_ready = True
