"""A still view refined while it holds: the chain on one captured view, a few iterations
at a time, stopping where a still render stops (chain.FrameRun.next_batch).

The live viewport mode draws its image after every step; the `preview` command
steps it headless. Both reach exactly the iterations `render --method ssr` runs for
the same view, so a converged preview is that render's SSR.
"""
import time

from .chain import ChainState, FrameRun
from .gpu_backend import StageTimer
from .inputs import ChainInputs

STEP_SECONDS = 0.05  # a step after the first adds iterations for about this long (the live view's tick)


class ProgressiveView:
    """The chain on PASSES (RenderPasses of one view) with SETTINGS, stepped until done.

    POOL (a gpu_backend.TexturePool) is reused from the view before, so a new view
    allocates nothing. INPUTS_TIMER (a StageTimer, the capture's) gets the upload;
    `timer` holds the chain's stage times of every step so far, the frame's own passes
    (lamp split, pyramids) included. The GPU backend must be up.
    """

    def __init__(self, passes, settings, pool=None, inputs_timer=None):
        self.state = ChainState.still()
        if pool is not None:
            self.state.pool = pool
        self.state.begin_frame(0)
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
