"""The live view orbiting the wet street (issue "Live while you navigate"): each moving view,
one iteration over the last view's reprojected history, is no further from a converged still
of that view than one iteration of its own passes without history. `make bench-live` measures
the same orbit; this holds its goal on every view."""
import pytest

from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.settings import ChainSettings

pytestmark = [pytest.mark.blender, pytest.mark.slow]


def test_history_helps_every_view_of_an_orbit_over_the_wet_street(gpu_backend, tmp_path):
    """24 views, 1 degree each, of a 320x180 view captured at 160x90 (the default Live
    Resolution), as the bench's orbit. The street's last views keep only a strip of wet ground
    along the frame's edge, where a history clipped to one iteration's noisy neighbourhood came
    out darker than no history at all."""
    from lab.bench.scenes import resolve_scene
    from lab.live_latency import orbit_quality
    _, rows, _ = orbit_quality(load_scene(resolve_scene("wet_street")), tmp_path, ChainSettings(), (160, 90), 24)
    assert len(rows) == 24
    worse = [(row["view"], round(row["moving"], 4), round(row["without_history"], 4))
             for row in rows if row["moving"] > row["without_history"]]
    assert not worse, f"views worse with history (view, moving, without history): {worse}"
