"""The one frame-sequence policy: which random numbers, quad pixel and history slot each
trace iteration gets, and when temporal history carries over.

Everything that renders frames (CLI, bench, operators, tests) goes through a
FrameSequence, so no caller computes a sample index of its own.

Sample indices: iteration i of frame f draws index f * STRIDE + i of the
Halton (2, 3) sequence. STRIDE is odd and prime to 3, so over any 2^a * 3^b
consecutive frames the indices visit every residue modulo 2^a and 3^b: each
pixel's points fill every Halton stratum, and the quad phase (the index
modulo 4) visits all four pixels of a 2x2 quad in four frames. STRIDE is
above the most iterations a still accumulates, so frames never share indices,
and a frame's numbers depend on its number alone (a resumed run draws the
same rays as an uninterrupted one).
"""
from dataclasses import dataclass

STRIDE = 257
MAX_ITERATIONS = STRIDE - 1


@dataclass(frozen=True)
class Iteration:
    sample_index: int    # in the Halton sequence
    quad_phase: int      # pixel of each 2x2 quad that originates the ray: 0..3
    noise_seed: int      # per-iteration seed of the ray-class coin
    read_slot: int       # history slot the temporal filter samples (None: no history)
    write_slot: int      # history slot it draws into; never read_slot


class FrameSequence:
    """Hands out trace iterations frame by frame.

    Every frame is rendered like a still: a frame with no history runs
    `accumulate_iterations` iterations, one with history runs one; then it doubles
    its iterations until its reflection settles (`noise_threshold`).
    still=True: every frame is a still (a single-frame render, a comparison
    tile), with no history from other frames. still=False: an animation: the
    history carries from frame to frame unless the range jumps or the camera
    cuts, so a frame that holds still starts out as converged as the last one
    and settles after an iteration or two.
    """

    def __init__(self, still=False):
        self.still = still
        self.frame = None
        self._camera = None
        self._iteration = 0
        self._slot = None   # history slot holding the latest filtered result, None: no history

    def start_frame(self, frame, camera=None):
        """Begin FRAME (seen through CAMERA, any hashable); returns True when history carries over."""
        continues = (not self.still and self.frame is not None and frame == self.frame + 1
                     and camera == self._camera)
        self.frame, self._camera, self._iteration = frame, camera, 0
        if not continues:
            self._slot = None
        return continues

    def forget(self):
        """Drop the history (a failed frame): the next frame starts afresh."""
        self.frame = None
        self._slot = None

    @property
    def has_history(self):
        return self._slot is not None

    def iteration_count(self, settings):
        """Iterations this frame runs (before any has run)."""
        if not settings.use_temporal or self.has_history:
            return 1
        return min(settings.accumulate_iterations, MAX_ITERATIONS)

    def doubling(self, settings):
        """Iterations a frame adds to double the ones it has run (its noise_threshold is not met yet),
        or 0 where it may not: no temporal filter, the threshold off, the cap."""
        if not (settings.use_temporal and settings.noise_threshold > 0):
            return 0
        return min(self._iteration, MAX_ITERATIONS - self._iteration)

    def next_iteration(self, keeps_history=True):
        """The next iteration of this frame; KEEPS_HISTORY False (temporal filter off) hands out no slots."""
        if self.frame is None:
            raise RuntimeError("FrameSequence.next_iteration before start_frame")
        if self._iteration >= MAX_ITERATIONS:
            raise RuntimeError(f"more than {MAX_ITERATIONS} iterations in frame {self.frame}")
        index = self.frame * STRIDE + self._iteration
        read = self._slot
        write = 0 if read is None else 1 - read
        self._iteration += 1
        self._slot = write if keeps_history else None
        return Iteration(sample_index=index % (1 << 32), quad_phase=index % 4,
                         noise_seed=_mix(index), read_slot=read, write_slot=write)


def _mix(value):
    """A 32-bit hash of an integer (splitmix64's finaliser), for per-iteration seeds."""
    value = (value + 0x9E3779B97F4A7C15) & 0xFFFFFFFFFFFFFFFF
    value = ((value ^ (value >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    value = ((value ^ (value >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
    return (value ^ (value >> 31)) & 0xFFFFFFFF
