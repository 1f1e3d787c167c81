"""When a frame's running mean has settled: the one measurement behind the convergence policy
(chain.FrameRun.next_batch).

The reflection at each check is kept on the GPU; the next check sums the change per
CONVERGENCE_TILE x CONVERGENCE_TILE tile in a shader (convergence_tiles.glsl) and reads back only
the tile sums. Downloading the whole reflection instead cost 80 ms per check at 1600x900 on an
H100, ten times the rest of the chain.
"""
import math

from .gpu_backend import download
from .gpu_passes import CONVERGENCE_TILE, CONVERGENCE_TILES, COPY


class ConvergenceCheck:
    """The reflection at the last check, kept from check to check and from frame to frame."""

    def __init__(self):
        self._reference_size = None  # of the reflection last checked; None: nothing to compare with

    def forget(self):
        """The next check has nothing to compare with (a new shot, a reset)."""
        self._reference_size = None

    def change(self, reflection_tx, pool):
        """The relative change (tile_change) of REFLECTION_TX since the last check, or None when
        there was none; REFLECTION_TX becomes the reference for the next check."""
        size = (reflection_tx.width, reflection_tx.height)
        reference_tx = pool.get("convergence_reference", size)
        change = None
        if self._reference_size == size:
            grid = (math.ceil(size[0] / CONVERGENCE_TILE), math.ceil(size[1] / CONVERGENCE_TILE))
            tiles_tx = pool.get("convergence_tiles", grid)
            CONVERGENCE_TILES.draw([tiles_tx], samplers=(("before_tx", reference_tx),
                                                                     ("after_tx", reflection_tx)))
            change = tile_change(download(tiles_tx))
        COPY.draw([reference_tx], samplers=(("source_tx", reflection_tx),))
        self._reference_size = size
        return change


def tile_change(tiles):
    """Change of premultiplied reflected radiance as a share of its level, per tile that mostly
    reflects, averaged over those tiles: a small glossy object counts as much as a large floor
    that converged long ago (a mean over pixels would call the still converged while the object
    is still noisy). TILES holds convergence_tiles.glsl's sums."""
    change, level, reflecting, pixels = (tiles[..., channel] for channel in range(4))
    counted = (reflecting >= 0.25 * pixels) & (level > 0)
    if not counted.any():
        return 0.0
    return float((change[counted] / level[counted]).mean())
