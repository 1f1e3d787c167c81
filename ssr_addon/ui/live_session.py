"""Live SSR in one 3D View: SSR follows the view as it moves, and refines once it holds.

A LiveSession is driven by `tick` (from a timer, never from a draw callback, where
EEVEE cannot draw offscreen); its `texture` is what ui.live's POST_PIXEL handler draws
over the view. It never reads bpy.context: the caller hands in the scene and the time.

- Each tick where the view moved, the view is captured at one sample (viewport_capture)
  and its first image costs one trace iteration, the history of the view before
  reprojected through the camera's motion as an animation's next frame is
  (progressive.NavigatedViews): SSR shows while the artist orbits.
- Once the view has held for DEBOUNCE_S, it is captured at the scene's viewport samples
  and refined as a still (progressive.ProgressiveView): each tick adds iterations for about
  STEP_SECONDS until it stops where a still render stops.
- History is dropped where it cannot hold: a jump the reprojection cannot follow, an edit of
  the scene (scene_updated), a setting of the chain; a setting the chain alone reads re-runs
  the chain on the captured passes, without a new capture.
The comparison modes (SSR, cubemap, planar, none) and the debug views apply as in
renders: a baseline mode shows EEVEE's own image with the baseline set up, once the view
holds. Images are shown through the scene's colour management (blender.colour_management), as
the 3D View shows EEVEE's; debug views, which are data, with the plain sRGB curve.
"""
import time
from collections import deque
from dataclasses import astuple

import numpy as np

from ..batch.frame import FrameFallbacks, add_view_captures, decide_view_cube, keep_view_captures
from ..blender.baselines import apply_baseline
from ..blender.colour_management import DisplayTransform, view_settings_key
from ..blender.gpu_context import ensure_backend
from ..blender.overrides import TemporaryChanges
from ..blender.render_setup import rendered_view_layer
from ..blender.viewport_capture import ViewportCapture, capture_problem
from ..core.errors import SSRError
from ..core.gpu_backend import StageTimer, TexturePool, upload
from ..core.layers import DEBUG_VIEW_LAYERS, debug_pixels, read_layers
from ..core.progressive import STEP_SECONDS, NavigatedViews
from .properties import chain_settings

DEBOUNCE_S = 0.3       # the view must hold this long before it is captured at the scene's samples
TICK_INTERVAL_S = 0.1  # how often the caller should tick
MOVING_SAMPLES = 1     # viewport samples of a capture while the view moves
RATE_WINDOW = 5        # updates the rate while moving is measured over


def live_capture_size(view_size, live_resolution):
    """The size a view of VIEW_SIZE (width, height) is captured and traced at, at LIVE_RESOLUTION
    percent (the Live Resolution setting); the overlay stretches the image over the view."""
    return tuple(max(int(side * live_resolution / 100.0), 4) for side in view_size)


class LiveSession:
    """Live SSR of one 3D View (SPACE, its WINDOW REGION and REGION_3D)."""

    def __init__(self, space, region, region_3d):
        self.space, self.region, self.region_3d = space, region, region_3d
        self.capture = ViewportCapture(space, region)
        self.fallbacks = FrameFallbacks(self.capture)  # the captures past the screen, drawn through this view
        self.pool = TexturePool()
        self.scene_version = 0       # bumped by scene_updated when the scene changes
        self._seen_version = 0
        self._absorb_updates = False  # the capture's own scene changes reach the caller late
        self._capture_key = self._chain_key = self._settings_seen = None
        self._changed_at = 0.0
        self._held = False           # the current view is captured at the scene's samples
        self._views = None           # the session's NavigatedViews, while in SSR mode
        self._following = None       # TemporaryChanges holding the capture's set-up while the view moves
        self._view = None            # the shown view's ProgressiveView (None in a baseline mode)
        self._passes = None
        self.display = DisplayTransform()
        self._image = None           # what is shown, scene linear: (texture, through the view transform)
        self._texture = None         # the same, display encoded
        self._shown = None           # (debug view, colour management) of what is shown
        self._capture_ms = 0.0
        self._capture_draws = 0
        self._updates = deque(maxlen=RATE_WINDOW)  # when each update while moving was shown
        self.draw_ms = 0.0           # the overlay's last draw (ui.live)
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
        return live_capture_size((self.region.width, self.region.height), scene.ssr.live_resolution)

    def _keys(self, scene):
        """(what the capture shows, what the chain reads): a change of the first captures anew,
        of the second re-runs the chain on the same passes; a debug view only redraws. What the
        capture shows is (the view, how it is captured): a change of the view alone is followed
        with its history. The navigation state is read as well as the matrices: those are
        recomputed only when the region redraws."""
        settings, view = scene.ssr, self.region_3d
        navigation = (*view.view_location, *view.view_rotation, view.view_distance, view.view_perspective,
                      view.view_camera_zoom, *view.view_camera_offset, self.space.lens,
                      self.space.clip_start, self.space.clip_end, scene.camera)
        matrices = np.round(np.concatenate([np.array(view.view_matrix), np.array(view.window_matrix)]), 5)
        chain = chain_settings(settings)
        return (((navigation, tuple(matrices.ravel())),
                 (self.capture_size(scene), self.space.shading.type, chain.lamp_split, settings.comparison_mode,
                  settings.probe_object, settings.planar_object)),
                astuple(chain))

    def scene_updated(self, scene, only_scene):
        """The depsgraph of SCENE was updated (ONLY_SCENE: no data-block but the scene itself).
        A change of the session's own settings is not an edit of what the view shows: tick
        reads those."""
        settings = (self._keys(scene)[1], scene.ssr.comparison_mode, scene.ssr.live_resolution,
                    scene.ssr.debug_view, self._look(scene))
        if not (only_scene and settings != self._settings_seen):
            self.scene_version += 1
        self._settings_seen = settings

    def tick(self, scene, now=None):
        """Advance the session; returns True when what is shown has changed. Raises SSRError
        when the session cannot go on (problem)."""
        now = time.perf_counter() if now is None else now
        problem = self.problem(scene)
        if problem is not None:
            raise SSRError(problem)
        capture_key, chain_key = self._keys(scene)
        if self._absorb_updates:
            self._seen_version, self._absorb_updates = self.scene_version, False
        edited = self.scene_version != self._seen_version
        if capture_key != self._capture_key or edited:
            moved = (self._capture_key is not None and capture_key[1] == self._capture_key[1]
                     and chain_key == self._chain_key)
            self._capture_key, self._chain_key, self._seen_version = capture_key, chain_key, self.scene_version
            self._changed_at, self._held = now, False
            if self._views is not None and moved and scene.ssr.comparison_mode == "SSR":
                if edited:
                    self._views.forget()
                    self._passes = None  # nor are the last view's captures what the scene shows now
                self._follow(scene, now)
                return True
            self._stop_following()
            self._views = self._view = self._passes = None
            changed = self._texture is not None
            self._texture = self._image = None
            self.status = "SSR live: waiting for the view to hold still"
            return changed
        if chain_key != self._chain_key:
            self._chain_key = chain_key
            if self._passes is not None:
                self._views = NavigatedViews(chain_settings(scene.ssr), self.pool)
                if self._held:  # the fallback may ask for other captures
                    self._add_captures(scene, self._passes, StageTimer())
                self._view = self._views.view(self._passes, follow=False)
                self._show(scene, self._view.step())
                return True
        if not self._held:
            if now - self._changed_at < DEBOUNCE_S:
                return False
            self._hold(scene)
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

    def _view_matrices(self):
        return np.array(self.region_3d.view_matrix), np.array(self.region_3d.window_matrix)

    def _follow(self, scene, now):
        """Capture the moving view at one sample and show its first image, the last view's history reprojected."""
        if self._following is None:
            self._following = TemporaryChanges()
            try:
                self.capture.hold_set_up(scene, rendered_view_layer(scene), self._following)
            finally:
                self._absorb_updates = True
        timer = StageTimer()
        passes = self._capture(scene, timer, MOVING_SAMPLES)
        if self._passes is not None:
            keep_view_captures(passes, self._passes)
        self._view, self._passes = self._views.view(passes, inputs_timer=timer), passes
        self._updates.append(now)
        self._show(scene, self._view.step(max_iterations=1))

    def _hold(self, scene):
        """Capture the held view at the scene's samples and show its first image, as a still."""
        settings = scene.ssr
        mode = settings.comparison_mode
        self._held = True
        self._updates.clear()
        self._stop_following()
        if mode != "SSR" or not chain_settings(settings).use_ssr:  # nothing to refine: EEVEE's own image
            size = self.capture_size(scene)
            with TemporaryChanges() as changes:
                apply_baseline(scene, mode.lower(), changes, probe_object=settings.probe_object,
                               mirror_object=settings.planar_object)
                try:
                    combined = self.capture.combined(scene, rendered_view_layer(scene), *self._view_matrices(), size)
                finally:
                    self._absorb_updates = True
            self._views = self._view = self._passes = None
            self._display(scene, upload(combined), view_transform=True)
            self.status = f"SSR live: {mode.lower()}, EEVEE's own image"
            return
        timer = StageTimer()
        passes = self._capture(scene, timer)
        self.fallbacks.reconsider()  # a view held elsewhere may need other levels
        self._add_captures(scene, passes, timer)
        if self._views is None:
            self._views = NavigatedViews(chain_settings(settings), self.pool)
        self._view, self._passes = self._views.view(passes, inputs_timer=timer, follow=False), passes
        outputs = self._view.step()
        if decide_view_cube(scene, passes, outputs, chain_settings(settings), self.fallbacks):
            self._add_captures(scene, passes, timer)
            self._view = self._views.view(passes, inputs_timer=timer, follow=False)
            outputs = self._view.step()
        self._capture_ms = sum(timer.milliseconds.values())
        self._show(scene, outputs)

    def _stop_following(self):
        """Put back the set-up held while the view moved."""
        if self._following is not None:
            following, self._following = self._following, None
            following.restore()
            self._absorb_updates = True

    def _capture(self, scene, timer, samples=None):
        """RenderPasses of the view, its noisy passes at SAMPLES (default: the scene's)."""
        settings = scene.ssr
        draws = self.capture.draws
        try:
            passes = self.capture.capture(scene, rendered_view_layer(scene), *self._view_matrices(),
                                          self.capture_size(scene), self._clip(scene),
                                          chain_settings(settings).lamp_split, timer, samples)
        finally:
            self._absorb_updates = True  # and any the capture caused by the time it failed
        ensure_backend()
        self._capture_ms = sum(timer.milliseconds.values())
        self._capture_draws = self.capture.draws - draws
        return passes

    def _add_captures(self, scene, passes, timer):
        """Give the held view's PASSES the captures past the screen its fallback asks for."""
        try:
            add_view_captures(scene, rendered_view_layer(scene), passes, chain_settings(scene.ssr), self.fallbacks,
                              scene.eevee.taa_samples, timer)
        finally:
            self._absorb_updates = True  # hiding the reflector for a planar capture is no edit

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

    @property
    def updates_per_second(self):
        """Of the view while it moves, over the last RATE_WINDOW updates; None before two."""
        if len(self._updates) < 2 or self._updates[-1] <= self._updates[0]:
            return None
        return (len(self._updates) - 1) / (self._updates[-1] - self._updates[0])

    def _show(self, scene, outputs):
        view = self._view
        debug_view = scene.ssr.debug_view
        if debug_view == "FINAL":
            self._display(scene, outputs["final"], view_transform=True)
        else:
            layers = read_layers(self._passes, outputs, names={DEBUG_VIEW_LAYERS[debug_view]})
            self._display(scene, upload(debug_pixels(None, layers, debug_view)), view_transform=False)
        chain_ms = sum(view.timer.milliseconds.values()) / view.iterations
        timings = (f"capture {self._capture_ms:.0f} ms ({self._capture_draws} draws), "
                   f"chain {chain_ms:.1f} ms per iteration, draw {self.draw_ms:.1f} ms")
        if not self._held:
            rate = self.updates_per_second
            self.status = f"SSR live: moving, {f'{rate:.1f} updates/s' if rate else 'following'}; {timings}"
        else:
            state = "converged" if view.done else "refining"
            self.status = f"SSR live: {view.iterations} iterations, {state}; {timings}"

    def release(self):
        self._stop_following()
        self.fallbacks.release()
        self.pool.release()
        self.display.release()
        self._views = self._view = self._texture = self._image = self._passes = None
