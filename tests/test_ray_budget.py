"""The expensive-ray budget: its histogram search gives exactly what sorting every traced
pixel gives (the definition), ties and sharp surfaces included."""
from dataclasses import replace

import numpy as np
import pytest

from ssr_addon.core.ray_budget import ray_budget
from ssr_addon.core.settings import ChainSettings

CLIP_END = 100.0


def sorted_budget(roughness, settings):
    """The definition: the allowed-th smoothest traced pixel is the threshold; ties at it share
    what is left of the budget."""
    traced = np.sort(roughness[roughness <= settings.max_roughness])
    if traced.size == 0 or settings.expensive_ray_budget >= 1.0:
        return 1.0, 1.0
    sharp = int(np.searchsorted(traced, settings.sharp_roughness, side="right"))
    allowed = max(int(settings.expensive_ray_budget * traced.size), sharp)
    if allowed == 0:
        return -1.0, 0.0
    threshold = float(traced[allowed - 1])
    below, ties = np.count_nonzero(traced < threshold), np.count_nonzero(traced == threshold)
    return threshold, (allowed - below) / ties


@pytest.mark.parametrize("kind", ["uniform", "two decimals", "constant", "mostly smooth", "all rough"])
def test_budget_matches_sorting_every_pixel(kind):
    rng = np.random.default_rng(abs(hash(kind)) % 2**32)
    for _ in range(60):
        n = int(rng.integers(1, 2000))
        roughness = {"uniform": rng.random(n), "two decimals": np.round(rng.random(n), 2),
                     "constant": np.full(n, rng.random()), "mostly smooth": rng.random(n) ** 6,
                     "all rough": np.ones(n)}[kind].astype(np.float32)[None, :]
        settings = replace(ChainSettings(), expensive_ray_budget=float(rng.random()),
                           sharp_roughness=float(rng.random() * 0.3), max_roughness=float(rng.choice([0.5, 1.0])))
        assert ray_budget(roughness, np.ones_like(roughness), CLIP_END, settings) == \
            sorted_budget(roughness, settings), (kind, settings)
