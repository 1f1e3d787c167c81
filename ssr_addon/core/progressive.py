"""A still view refined while it holds: the chain on one captured view, a few iterations
at a time, stopping where a still render stops (chain.FrameRun.next_batch); and a view on the
move, refined from the history of the views before it (NavigatedViews).

The live viewport mode draws its image after every step; the `preview` command
steps it headless. Both reach exactly the iterations `render --method ssr` runs for
the same view, so a converged preview is that render's SSR.
"""
import time
from dataclasses import replace

import numpy as np

from .chain import ChainState, FrameRun
from .gpu_backend import StageTimer
from .inputs import BACKGROUND_DEPTH, ChainInputs

STEP_SECONDS = 0.05  # a step after the first adds iterations for about this long (the live view's tick)
UNSEEN_MOTION = 1e6  # pixels: where a point the camera before did not see was on its screen (temporal.glsl)
HIDDEN_DEPTH_TOLERANCE = 0.02  # nearer by this share of its distance: in front of the point, hiding it


class ProgressiveView:
    """The chain on PASSES (RenderPasses of one view) with SETTINGS, stepped until done.

    A still (nothing carries over) unless STATE, a ChainState the caller has begun the view in,
    holds the history of the views before (NavigatedViews). POOL (a gpu_backend.TexturePool)
    is reused from the view before, so a new view allocates nothing. INPUTS_TIMER (a StageTimer, the capture's) gets the upload;
    `timer` holds the chain's stage times of every step so far, the frame's own passes
    (lamp split, pyramids) included. The GPU backend must be up.
    """

    def __init__(self, passes, settings, pool=None, inputs_timer=None, state=None):
        if state is None:
            state = ChainState.still()
            if pool is not None:
                state.pool = pool
            state.begin_frame(0)
        self.state = state
        self.settings = settings
        inputs = ChainInputs.from_passes(passes, settings, inputs_timer)
        self.timer = StageTimer()
        self.run = FrameRun(inputs, settings, self.state, self.timer)
        self._pending = self.run.next_batch()
        self.outputs = None

    @property
    def done(self):
        return self._pending == 0

    @property
    def iterations(self):
        return self.run.iterations

    def step(self, seconds=0.0, max_iterations=None):
        """Add iterations (at least one, at most MAX_ITERATIONS) until SECONDS have passed, then
        composite once; returns the ChainOutputs so far. Once done, changes nothing."""
        if not self.done:
            self.timer.resume()
            deadline = time.perf_counter() + seconds
            added = 0
            while max_iterations is None or added < max_iterations:
                self.run.iterate()
                added += 1
                self._pending -= 1
                if self._pending == 0:
                    self._pending = self.run.next_batch()
                if self.done or time.perf_counter() >= deadline:
                    break
            self.outputs = self.run.composite()
        return self.outputs


def camera_motion(depth, view_matrix, projection_matrix, previous_world_to_clip, previous_depth=None,
                  previous_world_to_view=None):
    """The Vector pass of a still scene seen by a moving camera: per pixel of DEPTH ((H, W)
    view-axis distances, image order; BACKGROUND_DEPTH for the world), the screen offset in
    pixels, y up, to where the camera before (PREVIOUS_WORLD_TO_CLIP) saw the same point. The
    world moves by direction alone. A surface point the camera before did not see has the motion
    UNSEEN_MOTION: off its screen or behind it, or, given its view (PREVIOUS_DEPTH, the same
    size, and PREVIOUS_WORLD_TO_VIEW), hidden behind what it showed there. Returns ((H, W, 2)
    float32, the share of surface pixels the camera before saw)."""
    height, width = depth.shape
    columns, rows = np.meshgrid(np.arange(width), np.arange(height))
    uv = np.stack([(columns + 0.5) / width, (height - rows - 0.5) / height], axis=-1)
    ndc = np.concatenate([uv * 2.0 - 1.0, np.full((height, width, 1), -1.0), np.ones((height, width, 1))], axis=-1)
    direction = ndc @ np.linalg.inv(np.asarray(projection_matrix, np.float64)).T
    direction = direction[..., :3] / direction[..., 3:]
    surface = depth < BACKGROUND_DEPTH
    # A surface point lies DEPTH along the view axis (-z); the world, at infinity, is a direction.
    point = np.where(surface[..., None], direction * (depth / -direction[..., 2])[..., None], direction)
    homogeneous = np.concatenate([point, surface[..., None].astype(np.float64)], axis=-1)
    view_to_world = np.linalg.inv(np.asarray(view_matrix, np.float64))
    clip = homogeneous @ (np.asarray(previous_world_to_clip, np.float64) @ view_to_world).T
    with np.errstate(divide="ignore", invalid="ignore"):
        previous_uv = np.where(clip[..., 3:] > 0.0, clip[..., :2] / clip[..., 3:] * 0.5 + 0.5, np.nan)
    seen = surface & np.all((previous_uv >= 0.0) & (previous_uv <= 1.0), axis=-1)
    if previous_depth is not None:
        distance = -(homogeneous @ (np.asarray(previous_world_to_view, np.float64) @ view_to_world).T)[..., 2]
        seen &= ~_hidden(np.where(seen[..., None], previous_uv, 0.5), distance, previous_depth)
    motion = (previous_uv - uv) * (width, height)
    motion[surface & ~seen] = UNSEEN_MOTION
    share = float(seen.sum() / surface.sum()) if surface.any() else 0.0
    return np.nan_to_num(motion, nan=UNSEEN_MOTION).astype(np.float32), share


def _hidden(previous_uv, distance, previous_depth):
    """Whether a point DISTANCE along the view axis of the camera before, at PREVIOUS_UV on its
    screen, lay behind what it showed there: nearer than the point by more than
    HIDDEN_DEPTH_TOLERANCE at all four texels around (a surface seen at a slant, between texels
    of other depths, is not hidden)."""
    height, width = previous_depth.shape
    position = previous_uv * (width, height) - 0.5
    low = np.floor(position).astype(int)
    farthest = np.zeros(distance.shape)
    for dx in (0, 1):
        for dy in (0, 1):
            column = np.clip(low[..., 0] + dx, 0, width - 1)
            row = height - 1 - np.clip(low[..., 1] + dy, 0, height - 1)
            farthest = np.maximum(farthest, previous_depth[row, column])
    return farthest < distance * (1.0 - HIDDEN_DEPTH_TOLERANCE)


def moving_view_settings(settings):
    """SETTINGS as a view on the move traces them: without sharp rays (use_sharp_rays). With them a
    mirror's one fresh ray is about as near a converged still as its reprojected history, so the
    history could no longer help there; without them the history carries the mirror's image (an
    orbit's moving views come nearer the stills than one iteration with them and no history), and
    each update traces a pass less."""
    return replace(settings, use_sharp_rays=False)


class NavigatedViews:
    """The views of a camera on the move over a still scene, each from a capture of its own,
    refined from the last one's history as an animation's frames are: the history is reprojected
    through the camera's motion (camera_motion), each view's first image costs one iteration, and a
    following view traces moving_view_settings.
    The history is dropped where reprojection cannot hold it: the camera before saw less than
    MIN_SHARED_VIEW of what this view shows (a cut), the view's size changed, or the caller says
    so (forget: the scene or a setting changed). POOL as ProgressiveView's."""

    MIN_SHARED_VIEW = 0.5

    def __init__(self, settings, pool=None):
        self.settings = settings
        self.state = ChainState(scene_holds_still=True)
        if pool is not None:
            self.state.pool = pool
        self._views = 0
        self._last_view = None  # (depth, world-to-view) of the last view

    def forget(self):
        self.state.reset_history()

    def view(self, passes, inputs_timer=None, follow=True):
        """Start a ProgressiveView of PASSES (a capture with no motion of its own) after the views
        before: FOLLOW, from their history; otherwise as a still, whose history the next view follows."""
        state, last_view = self.state, self._last_view
        # A history of another size reprojects nowhere.
        if not follow or last_view is None or last_view[0].shape != passes.depth.shape:
            self.forget()
        elif state.previous_world_to_clip is not None:
            motion, shared = camera_motion(passes.depth, passes.view_matrix, passes.projection_matrix,
                                           state.previous_world_to_clip, *last_view)
            passes = replace(passes, motion=motion)
            if shared < self.MIN_SHARED_VIEW:
                self.forget()
        state.begin_frame(self._views)  # the first view draws a still's own rays (ProgressiveView)
        self._views += 1
        self._last_view = (passes.depth, passes.view_matrix)
        settings = moving_view_settings(self.settings) if follow else self.settings
        return ProgressiveView(passes, settings, inputs_timer=inputs_timer, state=state)
