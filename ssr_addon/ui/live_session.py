"""Live SSR in one 3D View: capture once the view holds still, then refine step by step.

A LiveSession is driven by `tick` (from a timer, never from a draw callback, where
EEVEE cannot draw offscreen); its `texture` is what ui.live's POST_PIXEL handler draws
over the view. It never reads bpy.context: the caller hands in the scene and the time.

- While the view, the scene or a setting keeps changing, nothing is drawn: a stale
  image over a moving view misleads more than none.
- Once the view has held for DEBOUNCE_S, the passes are captured (viewport_capture)
  and a ProgressiveView starts: each tick adds iterations for about STEP_SECONDS and
  the image refines until it stops where a still render stops.
- Any change restarts it: the history belongs to one view.
The comparison modes (SSR, cubemap, planar, none) and the debug views apply as in
renders: a baseline mode shows EEVEE's own image with the baseline set up. Images are shown
through the scene's colour management (blender.colour_management), as the 3D View shows EEVEE's; debug
views, which are data, with the plain sRGB curve.
"""
import time
from dataclasses import astuple

import numpy as np

from ..blender.baselines import apply_baseline
from ..blender.colour_management import DisplayTransform, view_settings_key
from ..blender.gpu_context import ensure_backend
from ..blender.overrides import TemporaryChanges
from ..blender.render_setup import rendered_view_layer
from ..blender.viewport_capture import ViewportCapture, capture_problem
from ..core.errors import SSRError
from ..core.gpu_backend import StageTimer, TexturePool, upload
from ..core.layers import DEBUG_VIEW_LAYERS, debug_pixels, read_layers
from ..core.progressive import STEP_SECONDS, ProgressiveView
from .properties import chain_settings

DEBOUNCE_S = 0.3       # the view must hold this long before a capture starts
TICK_INTERVAL_S = 0.1  # how often the caller should tick


class LiveSession:
    """Live SSR of one 3D View (SPACE, its WINDOW REGION and REGION_3D)."""

    def __init__(self, space, region, region_3d):
        self.space, self.region, self.region_3d = space, region, region_3d
        self.capture = ViewportCapture(space, region)
        self.pool = TexturePool()
        self.scene_version = 0       # bumped by the caller when the scene changes (depsgraph updates)
        self._seen_version = 0
        self._absorb_updates = False  # the capture's own scene changes reach the caller late
        self._key = None
        self._changed_at = 0.0
        self._captured = False       # the current view has been captured
        self._view = None            # its ProgressiveView (None in a baseline mode)
        self._passes = None
        self.display = DisplayTransform()
        self._image = None           # what is shown, scene linear: (texture, through the view transform)
        self._texture = None         # the same, display encoded
        self._shown = None           # (debug view, colour management) of what is shown
        self._capture_ms = 0.0
        self.status = "SSR live: waiting for the view to hold still"

    @property
    def texture(self):
        return self._texture

    def problem(self, scene):
        """Why the session cannot go on in SCENE as the view is now, or None."""
        problem = capture_problem(scene, self.space)
        if problem is None and not self.region_3d.is_perspective:
            problem = "live SSR needs a perspective view"
        return problem

    def capture_size(self, scene):
        scale = scene.ssr.live_resolution / 100.0
        return max(int(self.region.width * scale), 4), max(int(self.region.height * scale), 4)

    def _view_key(self, scene):
        """Everything whose change restarts the view (a debug view only redraws). The navigation state is read as well as
        the matrices: those are recomputed only when the region redraws."""
        settings, view = scene.ssr, self.region_3d
        navigation = (*view.view_location, *view.view_rotation, view.view_distance, view.view_perspective,
                      view.view_camera_zoom, *view.view_camera_offset, self.space.lens,
                      self.space.clip_start, self.space.clip_end, scene.camera)
        matrices = np.round(np.concatenate([np.array(view.view_matrix), np.array(view.window_matrix)]), 5)
        return (navigation, tuple(matrices.ravel()), self.capture_size(scene), self.space.shading.type,
                astuple(chain_settings(settings)), settings.comparison_mode, settings.probe_object,
                settings.planar_object)

    def tick(self, scene, now=None):
        """Advance the session; returns True when what is shown has changed. Raises SSRError
        when the session cannot go on (problem)."""
        now = time.perf_counter() if now is None else now
        problem = self.problem(scene)
        if problem is not None:
            raise SSRError(problem)
        key = self._view_key(scene)
        if self._absorb_updates:
            self._seen_version, self._absorb_updates = self.scene_version, False
        if key != self._key or self.scene_version != self._seen_version:
            self._key, self._seen_version = key, self.scene_version
            self._changed_at, self._captured, self._view = now, False, None
            changed = self._texture is not None
            self._texture = self._image = None
            self.status = "SSR live: waiting for the view to hold still"
            return changed
        if not self._captured:
            if now - self._changed_at < DEBOUNCE_S:
                return False
            self._start(scene)
            return True
        if self._view is None:  # a baseline mode's still image
            return self._redisplay(scene)
        if self._view.done:
            if self._shown == self._look(scene):
                return False
            self._show(scene, self._view.outputs)
        else:
            self._show(scene, self._view.step(seconds=STEP_SECONDS))
        return True

    def _start(self, scene):
        """Capture the view and show its first image."""
        settings = scene.ssr
        mode = settings.comparison_mode
        size = self.capture_size(scene)
        timer = StageTimer()
        self._captured = True
        try:
            with TemporaryChanges() as changes:
                apply_baseline(scene, mode.lower(), changes, probe_object=settings.probe_object,
                               mirror_object=settings.planar_object)
                chain = chain_settings(settings)
                view = np.array(self.region_3d.view_matrix)
                projection = np.array(self.region_3d.window_matrix)
                view_layer = rendered_view_layer(scene)
                if mode != "SSR" or not chain.use_ssr:  # nothing to refine: EEVEE's own image, baseline applied
                    combined = upload(self.capture.combined(scene, view_layer, view, projection, size))
                    self._display(scene, combined, view_transform=True)
                    self.status = f"SSR live: {mode.lower()}, EEVEE's own image"
                    return
                passes = self.capture.capture(scene, view_layer, view, projection, size, self._clip(scene),
                                              chain.lamp_split, timer)
        finally:
            self._absorb_updates = True  # and any the capture caused by the time it failed
        ensure_backend()
        self._view, self._passes = ProgressiveView(passes, chain, self.pool, inputs_timer=timer), passes
        self._capture_ms = sum(timer.milliseconds.values())
        self._show(scene, self._view.step())

    def _clip(self, scene):
        """(clip_start, clip_end) of the view: the camera's in camera view, else the 3D View's."""
        if self.region_3d.view_perspective == "CAMERA" and scene.camera is not None:
            return scene.camera.data.clip_start, scene.camera.data.clip_end
        return self.space.clip_start, self.space.clip_end

    def _look(self, scene):
        """What decides how the shown image looks, besides the image itself."""
        return scene.ssr.debug_view, view_settings_key(scene), scene.view_settings.exposure

    def _display(self, scene, image_tx, view_transform):
        self._image = image_tx, view_transform
        self._texture = self.display.apply(scene, image_tx, self.pool, view_transform)
        self._shown = self._look(scene)

    def _redisplay(self, scene):
        """Show the same image again if the colour management changed; returns whether it did."""
        if self._image is None or self._shown == self._look(scene):
            return False
        self._display(scene, *self._image)
        return True

    def _show(self, scene, outputs):
        view = self._view
        debug_view = scene.ssr.debug_view
        if debug_view == "FINAL":
            self._display(scene, outputs["final"], view_transform=True)
        else:
            layers = read_layers(self._passes, outputs, names={DEBUG_VIEW_LAYERS[debug_view]})
            self._display(scene, upload(debug_pixels(None, layers, debug_view)), view_transform=False)
        chain_ms = sum(view.timer.milliseconds.values())
        state = "converged" if view.done else "refining"
        self.status = (f"SSR live: {view.iterations} iterations, {state}; capture {self._capture_ms:.0f} ms, "
                       f"chain {chain_ms / view.iterations:.1f} ms per iteration")

    def release(self):
        self.capture.release()
        self.pool.release()
        self.display.release()
        self._view = self._texture = self._image = self._passes = None

