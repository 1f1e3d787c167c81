"""Thin layer over Blender's `gpu` module: textures, full-screen passes, stage timing.

The backend must be up before any of it is used (blender.gpu_context.ensure_backend).

Textures hold images in OpenGL order (row 0 at the bottom); numpy arrays in
the rest of the add-on are in image order (row 0 at the top). `upload` and
`download` flip between the two so no other code has to care.
"""
import time

import gpu
import numpy as np
from gpu.types import GPUShaderCreateInfo, GPUStageInterfaceInfo

from .errors import SSRError
from .uniforms import pack_params

_FORMATS = {1: "R32F", 2: "RG32F", 4: "RGBA32F"}


def describe_gpu():
    return {"backend": gpu.platform.backend_type_get(), "renderer": gpu.platform.renderer_get(),
            "version": gpu.platform.version_get(), "vendor": gpu.platform.vendor_get()}


def upload(array):
    """A float texture holding ARRAY ((H, W) or (H, W, C), image order); 3 channels are padded to 4."""
    array = np.asarray(array, dtype=np.float32)
    if array.ndim == 2:
        array = array[..., None]
    height, width, channels = array.shape
    if channels == 3:  # flipped and padded in one copy
        pixels = np.empty((height, width, 4), np.float32)
        pixels[..., :3] = array[::-1]
        pixels[..., 3] = 1.0
        channels = 4
    elif channels in _FORMATS:
        pixels = np.ascontiguousarray(array[::-1])
    else:
        raise ValueError(f"cannot upload an array with {channels} channels")
    buffer = gpu.types.Buffer("FLOAT", pixels.size, pixels.ravel())
    return gpu.types.GPUTexture((width, height), format=_FORMATS[channels], data=buffer)


def empty_texture(size, channels=4):
    return gpu.types.GPUTexture(size, format=_FORMATS[channels])


def download(texture, channels=None):
    """The texture's pixels as an (H, W, C) float32 array in image order."""
    width, height = texture.width, texture.height
    # tex.read() advertises Fortran strides over C-ordered memory: ravel as stored.
    flat = np.asarray(texture.read(), dtype=np.float32).ravel(order="K")
    stored = flat.size // (width * height)
    pixels = flat.reshape(height, width, stored)[::-1]
    if channels is not None:
        pixels = pixels[..., :channels]
    return np.ascontiguousarray(pixels)


def uniform_buffer(fields):
    """A GPU uniform buffer holding the chain's parameter block (uniforms.PARAMS) with FIELDS."""
    return gpu.types.GPUUniformBuf(pack_params(fields).tobytes())


class FullscreenPass:
    """One fragment shader drawn over its whole target, declared with GPUShaderCreateInfo.

    `declare(info)` adds the pass's own resources (samplers, outputs); the
    fragment source is the shared GLSL prelude plus the pass's file.
    """

    def __init__(self, name, fragment_source, declare, typedefs=""):
        info = GPUShaderCreateInfo()
        interface = GPUStageInterfaceInfo(f"{name}_iface")
        interface.smooth("VEC2", "screen_uv")
        info.vertex_in(0, "VEC2", "position")
        info.vertex_out(interface)
        if typedefs:
            info.typedef_source(typedefs)
        declare(info)
        info.vertex_source("void main() { screen_uv = position * 0.5 + 0.5; gl_Position = vec4(position, 0.0, 1.0); }")
        info.fragment_source(fragment_source)
        try:
            self.shader = gpu.shader.create_from_info(info)
        except Exception as error:
            raise SSRError(f"GPU shader '{name}' failed to compile: {error}") from None
        from gpu_extras.batch import batch_for_shader
        self.batch = batch_for_shader(self.shader, "TRIS", {"position": ((-1, -1), (3, -1), (-1, 3))})
        self.name = name

    def draw(self, targets, samplers=(), uniform_blocks=(), constants=(), region=None):
        """Render into TARGETS (textures of one size); samplers, blocks and constants (int
        vectors, or floats) are (name, value) pairs; REGION (x, y, width, height) limits the draw.

        A texture may not be both sampled and drawn into: OpenGL leaves that undefined.
        """
        drawn_and_sampled = [name for name, texture in samplers if any(texture is target for target in targets)]
        assert not drawn_and_sampled, f"pass '{self.name}' samples {drawn_and_sampled} while drawing into it"
        framebuffer = gpu.types.GPUFrameBuffer(color_slots=tuple(targets))
        with framebuffer.bind():
            gpu.state.viewport_set(*(region or (0, 0, targets[0].width, targets[0].height)))
            gpu.state.blend_set("NONE")
            gpu.state.depth_test_set("NONE")
            self.shader.bind()
            for name, texture in samplers:
                self.shader.uniform_sampler(name, texture)
            for name, block in uniform_blocks:
                self.shader.uniform_block(name, block)
            for name, value in constants:
                if isinstance(value, float):
                    self.shader.uniform_float(name, value)
                else:
                    self.shader.uniform_int(name, value)
            self.batch.draw(self.shader)


class TexturePool:
    """Textures kept from frame to frame by role, re-created only when their size changes,
    so a long run's GPU memory stays flat."""

    def __init__(self):
        self._textures = {}

    def get(self, role, size, channels=4):
        key = (role, channels)
        texture = self._textures.get(key)
        if texture is None or (texture.width, texture.height) != tuple(size):
            texture = empty_texture(tuple(size), channels)
            self._textures[key] = texture
        return texture

    def release(self):
        self._textures.clear()


def wait_for(texture):
    """Return once the GPU has written TEXTURE: reading one pixel waits for the queued work."""
    framebuffer = gpu.types.GPUFrameBuffer(color_slots=(texture,))
    with framebuffer.bind():
        framebuffer.read_color(0, 0, 1, 1, 4, 0, "FLOAT")


class StageTimer:
    """Wall-clock milliseconds per stage.

    WAIT_FOR_GPU: wait for each GPU stage's output, so a stage's time is its own (benchmarks,
    the live view's per-iteration cost). Without it the GPU works through the queued stages
    while the CPU goes on, as a frame renders fastest: a GPU stage's time is then only its
    queueing, and the GPU's work shows in the first stage that reads a result back."""

    def __init__(self, wait_for_gpu=True):
        self.milliseconds = {}
        self.wait_for_gpu = wait_for_gpu
        self._start = time.perf_counter()

    def lap(self, stage, texture=None):
        """Close STAGE; with TEXTURE (its output) and wait_for_gpu, first wait until the GPU has written it."""
        if texture is not None and self.wait_for_gpu:
            wait_for(texture)
        now = time.perf_counter()
        self.milliseconds[stage] = self.milliseconds.get(stage, 0.0) + (now - self._start) * 1000.0
        self._start = now

    def resume(self):
        """Start timing again after a pause the stages should not count (a live view between ticks)."""
        self._start = time.perf_counter()


def lap(timer, stage, texture=None):
    """Close STAGE on TIMER (a StageTimer), where the caller was given one."""
    if timer:
        timer.lap(stage, texture)
