"""Cheap and expensive rays ("less than 20 % expensive rays"): which roughness splits the
traced pixels so that the smoothest get the Hi-Z tracer within the budget."""
import numpy as np

ROUGHNESS_BINS = 4096  # the histogram: only the bin holding the threshold is sorted


def ray_budget(roughness, depth, clip_end, settings):
    """(threshold, tie fraction) that gives the smoothest `expensive_ray_budget` share of
    traced pixels expensive rays, and every pixel at most `sharp_roughness`, even where
    large areas share one roughness. Exact, without sorting every pixel (40 ms at
    1600x900): a histogram finds the bin the threshold lies in, and only that bin is sorted."""
    traced = roughness[(depth < clip_end) & (roughness <= settings.max_roughness)]
    if traced.size == 0 or settings.expensive_ray_budget >= 1.0:
        return 1.0, 1.0
    sharp = int(np.count_nonzero(traced <= settings.sharp_roughness))
    allowed = max(int(settings.expensive_ray_budget * traced.size), sharp)
    if allowed == 0:
        return -1.0, 0.0
    bins = np.clip((traced * ROUGHNESS_BINS).astype(np.int32), 0, ROUGHNESS_BINS - 1)
    cumulative = np.cumsum(np.bincount(bins, minlength=ROUGHNESS_BINS))
    threshold_bin = int(np.searchsorted(cumulative, allowed))  # the bin holding the allowed-th smoothest
    below_bin = int(cumulative[threshold_bin - 1]) if threshold_bin > 0 else 0
    in_bin = np.sort(traced[bins == threshold_bin])
    threshold = float(in_bin[allowed - below_bin - 1])
    below = below_bin + np.count_nonzero(in_bin < threshold)
    ties = np.count_nonzero(in_bin == threshold)
    return threshold, (allowed - below) / ties
