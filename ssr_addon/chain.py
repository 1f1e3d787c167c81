"""The SSR chain: a plain function from textures and settings to textures.

No bpy.context here: callers (CLI, operators, tests) hand in GPU textures and
the camera, and get GPU textures back. Stage timings go into a StageTimer.
"""
from dataclasses import dataclass

import numpy as np

from .gpu_backend import empty_texture, upload
from .shaders import get_pass, pack_params


@dataclass
class ChainInputs:
    """Per-frame inputs, as textures at full resolution."""
    radiance_tx: object         # lit scene colour the reflections are fetched from
    depth_tx: object
    normal_tx: object
    roughness_tx: object
    combined_tx: object
    specular_color_tx: object
    specular_indirect_tx: object
    view_matrix: np.ndarray
    projection_matrix: np.ndarray
    clip_start: float
    clip_end: float

    @property
    def size(self):
        return self.depth_tx.width, self.depth_tx.height

    @classmethod
    def from_passes(cls, passes):
        """Upload FramePasses; the lit scene (Combined) is also what reflections show."""
        combined_tx = upload(passes.combined)
        return cls(
            radiance_tx=combined_tx, depth_tx=upload(passes.depth), normal_tx=upload(passes.normal),
            roughness_tx=upload(passes.roughness), combined_tx=combined_tx,
            specular_color_tx=upload(passes.specular_color),
            specular_indirect_tx=upload(passes.specular_indirect),
            view_matrix=passes.view_matrix, projection_matrix=passes.projection_matrix,
            clip_start=passes.clip_start, clip_end=passes.clip_end)


@dataclass
class ChainOutputs:
    hit_tx: object         # (hit uv, hit distance, confidence)
    reflection_tx: object  # (reflected radiance, confidence)
    final_tx: object       # composited image


def trace_params(inputs, settings):
    return pack_params(inputs.projection_matrix, inputs.view_matrix, inputs.size,
                       inputs.clip_start, inputs.clip_end, settings)


def trace_hits(inputs, settings, params, timer=None):
    hit_tx = empty_texture(inputs.size)
    framebuffer = get_pass("trace_linear").draw(
        [hit_tx], samplers=(("depth_tx", inputs.depth_tx), ("normal_tx", inputs.normal_tx),
                            ("roughness_tx", inputs.roughness_tx)),
        uniform_blocks=(("params", params),))
    if timer:
        timer.lap("trace", framebuffer)
    return hit_tx


def run_chain(inputs, settings, timer=None):
    """Trace, resolve and composite one frame; returns ChainOutputs."""
    params = trace_params(inputs, settings)
    hit_tx = trace_hits(inputs, settings, params, timer)
    reflection_tx = empty_texture(inputs.size)
    framebuffer = get_pass("resolve").draw(
        [reflection_tx], samplers=(("hit_tx", hit_tx), ("radiance_tx", inputs.radiance_tx),
                                   ("roughness_tx", inputs.roughness_tx)),
        uniform_blocks=(("params", params),))
    if timer:
        timer.lap("resolve", framebuffer)
    final_tx = empty_texture(inputs.size)
    framebuffer = get_pass("composite").draw(
        [final_tx], samplers=(("combined_tx", inputs.combined_tx),
                              ("specular_color_tx", inputs.specular_color_tx),
                              ("specular_indirect_tx", inputs.specular_indirect_tx),
                              ("reflection_tx", reflection_tx)),
        uniform_blocks=(("params", params),))
    if timer:
        timer.lap("composite", framebuffer)
    return ChainOutputs(hit_tx=hit_tx, reflection_tx=reflection_tx, final_tx=final_tx)
