"""The comparison modes: a frame with SSR, one reflection cubemap, a planar reflection or no
reflections (blender.baselines), one at a time or side by side with the cost of each."""
import time
from dataclasses import replace

import numpy as np

from ..blender.baselines import COMPARISON_MODES, apply_baseline
from ..blender.comparison_sheet import comparison_sheet
from ..blender.overrides import TemporaryChanges
from ..blender.render_setup import render_size
from ..blender.scene_io import require_camera
from ..core.errors import SSRError
from .frame import render_frame

# The render method of each comparison mode, rendered with the mode's baseline applied:
# EEVEE uses plane probes only with its screen-trace ray tracing.
MODE_METHODS = {"SSR": "ssr", "CUBEMAP": "none", "PLANAR": "eevee-rt", "NONE": "none"}
WARM_UP_MIN = 16  # pixels: the smallest side of a warm-up render


def render_mode(scene, mode, request, state=None, fallbacks=None, probe_object=None, mirror_object=None):
    """Render the scene's current frame in comparison MODE (COMPARISON_MODES); returns render_frame's result.

    STATE (a chain.ChainState) and FALLBACKS (frame.FrameFallbacks) carry SSR's temporal history
    and fallback levels between the frames of an animation; probe_object and mirror_object choose
    the baselines' cubemap centre and mirror plane.
    """
    require_camera(scene)
    with TemporaryChanges() as changes:
        apply_baseline(scene, mode.lower(), changes, probe_object=probe_object, mirror_object=mirror_object)
        return render_frame(scene, replace(request, method=MODE_METHODS[mode]), state, fallbacks)


def compare_modes(scene, request, probe_object=None, mirror_object=None):
    """The current frame in every comparison mode, side by side: (sheet rgba, label per mode, problems).

    Each mode is timed after a warm-up render of its own at a quarter of the size: a mode's
    first render compiles EEVEE's shaders for its set-up (a minute in a fresh cache), which
    says nothing of what the mode costs. A mode the scene cannot show (no mirror plane...)
    gets a blank tile and a line in problems.
    """
    require_camera(scene)
    width, height = render_size(scene, request.resolution)
    warm_up = replace(request, resolution=(max(WARM_UP_MIN, width // 4), max(WARM_UP_MIN, height // 4)))
    tiles, problems = [], []
    for mode, label, _ in COMPARISON_MODES:
        try:
            render_mode(scene, mode, warm_up, probe_object=probe_object, mirror_object=mirror_object)
            started = time.perf_counter()
            images, _ = render_mode(scene, mode, request, probe_object=probe_object, mirror_object=mirror_object)
        except SSRError as error:
            problems.append(f"{label}: {error}")
            tiles.append(([label, "n/a"], None))
            continue
        tiles.append(([label, f"{time.perf_counter() - started:.1f} s"], images.final))
    shape = next((rgba.shape for _, rgba in tiles if rgba is not None), None)
    if shape is None:
        raise SSRError("; ".join(problems))
    tiles = [(lines, np.zeros(shape, np.float32) if rgba is None else rgba) for lines, rgba in tiles]
    return comparison_sheet(tiles), [" ".join(lines) for lines, _ in tiles], problems
